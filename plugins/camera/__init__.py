"""Cameras through OpenCV: a webcam or a video file as RGB images with capture times (docs/camera.md).

``video`` reads frames without the runtime, ``synthetic`` writes counter videos for tests and the
docs, ``node`` is the ``camera.opencv`` node."""
