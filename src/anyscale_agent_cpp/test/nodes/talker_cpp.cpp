// Test fixture node (roscpp): publishes std_msgs/String on ~topic at ~rate Hz, or, with
// ~payload_bytes > 0, a sensor_msgs/Image of about that size (camera-like load for benchmarks).
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>

int main(int argc, char** argv)
{
  ros::init(argc, argv, "talker_cpp");
  ros::NodeHandle nh, pnh("~");
  const double rate_hz = pnh.param("rate", 10.0);
  const int payload = pnh.param("payload_bytes", 0);
  const std::string topic = pnh.param<std::string>("topic", "chatter");
  ros::Publisher pub;
  std_msgs::String text;
  sensor_msgs::Image image;
  if (payload > 0)
  {
    pub = nh.advertise<sensor_msgs::Image>(topic, 2);
    image.width = 640;
    image.step = 3 * image.width;
    image.height = std::max(1, payload / int(image.step));
    image.encoding = "rgb8";
    image.data.resize(image.step * image.height);
  }
  else
  {
    pub = nh.advertise<std_msgs::String>(topic, 10);
    text.data = pnh.param<std::string>("text", "hello");
  }
  ros::Rate rate(rate_hz);
  while (ros::ok())
  {
    if (payload > 0)
    {
      image.header.stamp = ros::Time::now();
      pub.publish(image);
    }
    else
    {
      pub.publish(text);
    }
    ros::spinOnce();
    rate.sleep();
  }
  return 0;
}
