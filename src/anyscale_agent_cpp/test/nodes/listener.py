#!/usr/bin/python3
"""Test fixture node (rospy): subscribes to ~topic (std_msgs/String) and does nothing else, a
rospy subscriber whose bus statistics the agent reads."""
import rospy
from std_msgs.msg import String


def main():
    rospy.init_node("listener")
    rospy.Subscriber(rospy.get_param("~topic", "chatter"), String, lambda _msg: None, queue_size=1)
    rospy.spin()


if __name__ == "__main__":
    main()
