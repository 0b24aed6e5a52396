"""Hands: the 57 static-gesture features, a kinematic hand model and calibrated gesture poses.

Modules:

- ``features``: the paper's 57 features of a contract hand (``cbgo/hands/frame``), exactly as
  the real recordings define them (``hand_features``, ``hands_features``).
- ``model``: ``HandShape`` (a person's anatomy), ``HandPose`` (joint angles and palm
  orientation), ``build_hand`` (every field of a contract hand), ``blend``, ``neutral_pose``.
- ``poses``: the 8 static gestures as calibrated mean poses and spreads (``gesture_pose``).
- ``poses.json`` is fitted to the real recordings by ``cbgo train hands`` (an offline tool).
- ``data``: the vendored real recordings (``load_real_features``).

Rule: everything here is pure computation on numpy (the calibration is an offline tool); nothing
touches Zenoh. ``cbgo bench hands`` measures how real the simulated hands look.
"""
