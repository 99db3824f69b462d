"""Hardware abstraction: RealSense, V4L2 and replay cameras behind one interface."""
