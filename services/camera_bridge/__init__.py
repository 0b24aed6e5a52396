"""camera-bridge: hand frames from an ordinary webcam, a video file or a folder of images."""
