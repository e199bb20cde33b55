#!/usr/bin/python3
"""Test fixture node (rospy): subscribes to `chatter` (remap it) and counts what arrives."""
import rospy
from std_msgs.msg import String


def main():
    rospy.init_node("listener")
    count = [0]

    def on_message(_msg):
        count[0] += 1
        if count[0] % 100 == 1:
            rospy.loginfo("listener: %d messages", count[0])

    rospy.Subscriber("chatter", String, on_message, queue_size=10)
    rospy.spin()


if __name__ == "__main__":
    main()
