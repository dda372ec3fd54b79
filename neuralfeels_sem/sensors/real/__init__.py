"""Hardware backends: DIGIT, RealSense, Allegro (CAN), Dynamixel hand, ArUco object pose, RealSensor."""
