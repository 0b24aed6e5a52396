"""The focus of an episode: where the person's attention was, in the robot base frame (m).

Rules:
- **Gaze** (preferred): the ``cbgo/gaze`` points received during the episode (and up to a
  look-back before it: people look at the object before they gesture). An eye tracker's stream
  has blinks, saccades and glances elsewhere, so the estimate is robust: the coordinate-wise
  median, then the mean of the points within ``k`` median absolute deviations (at least
  ``floor_m``) of it. Fewer than ``min_points`` gaze points count as no gaze.
- **Pointing** (without gaze): the index finger's ray (knuckle → tip, in the base frame through
  the frames' ``to_base``) of the frames the static classifier labelled ``point``, intersected
  with the table plane z = 0. Rays that do not go down, or hit the table behind their origin or
  farther than ``max_range_m``, are ignored; the hits are combined robustly as above.
- Otherwise no focus (``focus: null, focus_source: null``).

Which sources are tried, in which order, is configurable (``focus: gaze,pointing``). Pure numpy,
no Zenoh.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

TABLE_Z = 0.0


def robust_center(points: Iterable[Sequence[float]], k: float = 3.0, floor_m: float = 0.02
                  ) -> np.ndarray | None:
    """Returns an outlier-robust centre of 3-D points, or None for no points.

    The median, then the mean of the points whose distance to it is at most
    max(k · median distance, floor_m).
    """
    pts = np.asarray(list(points), dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        return None
    median = np.median(pts, axis=0)
    dist = np.linalg.norm(pts - median, axis=1)
    keep = dist <= max(k * float(np.median(dist)), floor_m)
    return pts[keep].mean(axis=0)


def table_hit(origin: np.ndarray, direction: np.ndarray, max_range_m: float = 3.0,
              plane_z: float = TABLE_Z) -> np.ndarray | None:
    """Returns where a ray meets the table plane, or None if it does not (in front, in range).

    Args:
        origin: the ray's start, base frame (m).
        direction: the ray's direction (any length).
        max_range_m: hits farther than this from the origin are ignored.
        plane_z: the table's height.
    """
    direction = np.asarray(direction, dtype=float)
    norm = np.linalg.norm(direction)
    if norm == 0 or direction[2] / norm > -1e-3:  # parallel to or away from the table
        return None
    d = direction / norm
    s = (plane_z - origin[2]) / d[2]
    if s <= 0 or s > max_range_m:
        return None
    hit = origin + s * d
    hit[2] = plane_z
    return hit


def pointing_focus(rays: Iterable[tuple[np.ndarray, np.ndarray]], max_range_m: float = 3.0
                   ) -> np.ndarray | None:
    """Returns the robust centre of the table hits of pointing rays, or None if none hits."""
    hits = [h for h in (table_hit(o, d, max_range_m) for o, d in rays) if h is not None]
    return robust_center(hits) if hits else None


def choose_focus(order: Sequence[str], gaze_points: list, rays: list, min_gaze_points: int = 3,
                 max_range_m: float = 3.0) -> tuple[list[float] | None, str | None]:
    """Returns (focus, focus_source) from the first source in `order` that has one.

    Args:
        order: source names, ``gaze`` and/or ``pointing``, in order of preference.
        gaze_points: base-frame gaze points of the episode.
        rays: base-frame (origin, direction) pointing rays of the episode's point frames.
        min_gaze_points: fewer gaze points than this count as no gaze.
        max_range_m: the longest pointing ray considered.
    """
    for source in order:
        if source == "gaze" and len(gaze_points) >= min_gaze_points:
            focus = robust_center(gaze_points)
        elif source == "pointing":
            focus = pointing_focus(rays, max_range_m)
        else:
            continue
        if focus is not None:
            return [float(v) for v in focus], source
    return None, None
