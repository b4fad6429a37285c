"""The ROS 1 channel adapter: master API (XML-RPC), TCPROS, registration watchdog."""
