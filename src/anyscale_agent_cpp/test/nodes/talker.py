#!/usr/bin/python3
"""Test fixture node (rospy): publishes on ~topic at ~rate Hz; ~payload_bytes pads a
sensor_msgs/Image when > 0 (camera-like load for the benchmark), else std_msgs/String."""
import rospy
from sensor_msgs.msg import Image
from std_msgs.msg import String


def main():
    rospy.init_node("talker")
    rate_hz = float(rospy.get_param("~rate", 10.0))
    topic = rospy.get_param("~topic", "chatter")
    payload = int(rospy.get_param("~payload_bytes", 0))
    if payload > 0:
        pub = rospy.Publisher(topic, Image, queue_size=2)
        width = 640
        msg = Image(height=max(1, payload // (3 * width)), width=width, encoding="rgb8",
                    step=3 * width)
        msg.data = bytes(msg.height * msg.step)
    else:
        pub = rospy.Publisher(topic, String, queue_size=10)
        msg = String(data=rospy.get_param("~text", "hello"))
    rate = rospy.Rate(rate_hz)
    while not rospy.is_shutdown():
        if payload > 0:
            msg.header.stamp = rospy.Time.now()
        pub.publish(msg)
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


if __name__ == "__main__":
    main()
