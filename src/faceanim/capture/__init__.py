"""From video to motion: reading frames, tracking the face, head pose, neutral, filtering, FAPs.

Video (PyAV) and tracking (MediaPipe) are imported only when used; install them with
``pip install faceanim[capture]``.
"""
