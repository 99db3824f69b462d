"""2D body landmarks: MediaPipe Pose (BlazePose full) run by onnxruntime, and the landmark recording format."""
