"""Benchmark camera-bridge: labelled images and videos through the bridge and static-gesture.

Figures:

1. **Per-class accuracy through the live services.** A router, static-gesture and camera-bridge
   run as processes; each labelled item goes in through ``--camera`` as a user's would (the
   images of all classes as one folder, each held ``--hold-s`` with a gap after it; each video
   on its own clock) and every ``gestures/static`` answer is scored against the item's label:
   - a label in the model's vocabulary: the share of camera frames answered with it (frames
     where MediaPipe found no hand count as wrong);
   - any other label (out of the vocabulary, e.g. ``relaxed``): the share answered ``none`` or
     with a top probability below 0.5 (rejected).
2. **End-to-end latency**: from a frame's capture time (its ``ts``: when the camera delivered
   it) to the arrival of its ``gestures/static`` at a separate subscriber, p50/p95 (ms).
3. **The bridge's per-frame time**: MediaPipe and the geometry, in this process, on the frames
   of a 640×480 video (``--speed-video``): wall and CPU ms per frame, p50/p95.
4. **CPU use at 30 fps**: camera-bridge as a process playing that video at 30 fps for
   ``--seconds``: the process's CPU time over wall time (% of one core), and the frames it had
   to skip to keep up.
5. **Features side by side** (when the data has ``thumbsup``): the static model's 45
   device-independent features (`invariant.derive`) of the real Leap recordings' thumbs-up,
   of simulated Leap thumbs-ups and of camera-bridge's thumbs-ups, and how many standard
   deviations of the real ones each camera feature lies from their mean.
6. **The landmark filter** (with the fixtures): how much a still hand's palm shakes between
   frames and how fast it seems to move, raw and One-Euro-filtered, and how far the filtered
   palm trails the raw one on the reaching hand (`cbgo.services.camera_bridge.smoothing`).
7. **Orientation**: the static model (in-process) on each item's camera hands as seen and
   turned about the palm to a Leap user's hold (palm down, fingers forward): the 57 features
   are pitch and yaw angles, which depend on how the hand is turned and lose the yaw when a
   bone points straight up or down.

Labelled data (``--data DIR``): one folder per label (``thumbsup/``, ``four/``, ``relaxed/``
...), each holding images (.jpg .jpeg .png .bmp .webp) and/or videos (.mp4 .avi .mov .mkv
.webm). Without it, the fixtures of ``tests/fixtures/camera`` (two thumbs-up photos, a
thumbs-up video, an open relaxed hand reaching out: out of the vocabulary).

Examples::

    cbgo bench camera
    cbgo bench camera --data ~/camera-poses --hold-s 3
    cbgo bench camera --write docs/results/camera_bridge.md
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from cbgo import keys, wire

IMAGES = (".jpg", ".jpeg", ".png", ".bmp", ".webp")
VIDEOS = (".mp4", ".avi", ".mov", ".mkv", ".webm")
FIXTURES = Path(__file__).resolve().parents[3] / "tests" / "fixtures" / "camera"
DEFAULT_SET = {"thumbsup": ["thumbs_up_photos/1_hand_thumb_up.jpg",
                            "thumbs_up_photos/2_two_thumbs_up.jpg", "thumbs_up_clip.mp4"],
               "relaxed": ["open_palm_reaching.mp4"]}
RATE_HZ = 15.0  # images: the folder's frame rate
START_S = 120.0  # how long a service may take to come up on a loaded machine


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--data", type=Path, default=None,
                        help="a folder with one sub-folder of images/videos per label "
                             "[the fixtures in tests/fixtures/camera]")
    parser.add_argument("--hold-s", type=float, default=2.0,
                        help="images: seconds each one is shown [2]")
    parser.add_argument("--speed-video", type=Path, default=FIXTURES / "thumbs_up_clip.mp4",
                        help="the 640x480 video of the speed and CPU figures")
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="how long the CPU use at 30 fps is measured [20]")
    parser.add_argument("--model-complexity", type=int, default=1, choices=(0, 1),
                        help="MediaPipe's landmark model for every figure [1]")


def labelled_items(data: Path | None) -> dict[str, list[Path]]:
    """Returns label -> image and video files, from ``--data`` or the fixtures."""
    if data is None:
        return {label: [FIXTURES / f for f in files] for label, files in DEFAULT_SET.items()}
    out = {}
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGES + VIDEOS)
        if files:
            out[folder.name] = files
    if not out:
        raise SystemExit(f"no labelled images or videos under {data}: one folder per label")
    return out


class Answers:
    """A separate subscriber's view: hand frames and static answers, with arrival times."""

    def __init__(self, session, stack):
        self.lock = threading.Lock()
        self.frames: dict[int, dict] = {}
        self.static: list[tuple[float, dict]] = []
        session.declare_subscriber(stack.keys.of(keys.HANDS_FRAME), self._on_frame)
        session.declare_subscriber(stack.keys.of(keys.GESTURES_STATIC), self._on_static)

    def _on_frame(self, sample) -> None:
        message = wire.decode(sample.payload.to_bytes())
        with self.lock:
            self.frames[message["seq"]] = message

    def _on_static(self, sample) -> None:
        arrived = time.time()
        with self.lock:
            self.static.append((arrived, wire.decode(sample.payload.to_bytes())))

    def take(self) -> tuple[dict[int, dict], list[tuple[float, dict]]]:
        """Returns what arrived since the last call, and forgets it."""
        with self.lock:
            frames, static = self.frames, self.static
            self.frames, self.static = {}, []
        return frames, static


def play(stack, answers: Answers, camera: str, flags: list[str], complexity: int
         ) -> tuple[dict[int, dict], list[tuple[float, dict]], dict]:
    """Plays one source through camera-bridge; returns its frames, answers and last status."""
    stack.start_service("camera-bridge", "--camera", camera, "--wait-for", "static-gesture",
                        "--model-complexity", str(complexity), *flags)
    stack.wait_alive(["camera-bridge"], timeout=START_S)
    while True:
        status = stack.status("camera-bridge")
        if status["reading"]["state"] == "finished":
            break
        time.sleep(0.2)
    sent = status["frames"]
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:  # until static-gesture has read the last frame
        if stack.status("static-gesture")["counters"]["received"] >= play.received + sent:
            break
        time.sleep(0.1)
    time.sleep(0.5)  # the answer to the last frame is on its way
    play.received = stack.status("static-gesture")["counters"]["received"]
    stack.stop("camera-bridge")
    frames, static = answers.take()
    return frames, static, status


play.received = 0


def answers_by_item(frames: dict[int, dict], static: list[tuple[float, dict]],
                    item_of=lambda seq: 0) -> dict[int, dict]:
    """Returns, per item, each answered frame's (top name, its p) and the latencies (ms)."""
    by_seq = {m["seq"]: (t, m) for t, m in static}
    items: dict[int, dict] = defaultdict(lambda: {"tops": [], "latency": []})
    for seq, frame in frames.items():
        if seq not in by_seq:
            continue  # no hand in the frame (or its answer was dropped): nothing answered
        arrived, message = by_seq[seq]
        p = np.asarray(message["probs"])
        item = items[item_of(seq)]
        item["tops"].append((message["names"][int(np.argmax(p))], float(p.max())))
        item["latency"].append((arrived - frame["ts"]) * 1e3)
    return items


def row_of(label: str, name: str, item: dict | None, shown: int, vocabulary: list[str]) -> dict:
    """Returns one item's figures.

    In the vocabulary: the frames answered with its label. Outside it: the frames rejected
    (answered none, below p 0.5, or not at all: no hand seen).
    """
    tops = item["tops"] if item else []
    answers = Counter(top for top, _ in tops)
    inside = label in vocabulary
    if inside:
        good = sum(top == label for top, _ in tops)
    else:
        good = (shown - len(tops)) + sum(top == "none" or p < 0.5 for top, p in tops)
    return {"label": label, "name": name, "shown": shown, "answered": len(tops),
            "answers": answers, "in_vocabulary": inside, "good": good,
            "score": good / max(shown, 1)}


def accuracy(data: Path | None, hold_s: float, complexity: int) -> tuple[list[dict], list]:
    """Figures 1 and 2: every labelled item through the live services."""
    from cbgo.services.static_gesture.classifier import StaticClassifier, default_model_path
    from cbgo.testing import Stack

    vocabulary = StaticClassifier.load(default_model_path()).names
    labelled = labelled_items(data)
    rows, latencies = [], []
    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.wait_alive(["router"])
        answers = Answers(stack.session(), stack)
        stack.start_service("static-gesture")
        stack.wait_alive(["static-gesture"], timeout=START_S)
        images = [(label, f) for label, files in labelled.items() for f in files
                  if f.suffix.lower() in IMAGES]
        if images:
            folder = Path(tmp) / "images"
            folder.mkdir()
            for k, (_, f) in enumerate(images):
                shutil.copy(f, folder / f"{k:05d}{f.suffix.lower()}")
            held, gap = round(hold_s * RATE_HZ), round(0.5 * RATE_HZ)
            frames, static, _ = play(stack, answers, str(folder), [
                "--hold-s", str(hold_s), "--gap-s", "0.5", "--rate-hz", str(RATE_HZ)],
                complexity)
            items = answers_by_item(frames, static, lambda seq: seq // (held + gap))
            for k, (label, f) in enumerate(images):
                rows.append(row_of(label, f.name, items.get(k), held, vocabulary))
                latencies += items[k]["latency"] if k in items else []
        for label, files in labelled.items():
            for f in (f for f in files if f.suffix.lower() in VIDEOS):
                frames, static, status = play(stack, answers, str(f), [], complexity)
                item = answers_by_item(frames, static).get(0)
                rows.append(row_of(label, f.name, item, status["reading"]["read"], vocabulary))
                latencies += item["latency"] if item else []
    return rows, latencies


def camera_hands(files: list[Path], complexity: int) -> list[dict]:
    """Returns the contract hands camera-bridge's geometry makes of images and video frames."""
    import cv2

    from cbgo.services.camera_bridge import geometry
    from cbgo.services.camera_bridge.main import user_side
    from cbgo.services.camera_bridge.tracker import HandTracker

    pose, hands = geometry.CameraPose(), []
    for f in files:
        still = f.suffix.lower() in IMAGES
        tracker = HandTracker(model_complexity=complexity, still_images=still)
        capture = None if still else cv2.VideoCapture(str(f))
        while True:
            image = cv2.imread(str(f)) if still else capture.read()[1]
            if image is None:
                break
            height, width = image.shape[:2]
            K = geometry.camera_matrix(width, height)
            for d in tracker.detect(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))[:1]:
                shift = geometry.solve_translation(d.world_m, d.image_px, K)
                points = pose.to_leap((d.world_m + shift) * 1000.0)
                hands.append(geometry.leap_hand(points, user_side(d.label, False), 1, d.score))
            if still:
                break
        tracker.close()
    return hands


def palm_paths(video: Path, complexity: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Returns the times (s), raw and One-Euro-filtered palm positions (mm) of a video's hand.

    Every frame is processed (none skipped), on the video's own clock.
    """
    import cv2

    from cbgo.services.camera_bridge import geometry
    from cbgo.services.camera_bridge.main import user_side
    from cbgo.services.camera_bridge.smoothing import OneEuro
    from cbgo.services.camera_bridge.tracker import HandTracker

    capture = cv2.VideoCapture(str(video))
    fps = capture.get(cv2.CAP_PROP_FPS) or 30.0
    tracker, pose, smooth = HandTracker(model_complexity=complexity), geometry.CameraPose(), None
    times, raw, filtered = [], [], []
    n = 0
    while True:
        ok, image = capture.read()
        if not ok:
            break
        height, width = image.shape[:2]
        K = geometry.camera_matrix(width, height)
        found = tracker.detect(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))[:1]
        for d in found:
            shift = geometry.solve_translation(d.world_m, d.image_px, K)
            points = pose.to_leap((d.world_m + shift) * 1000.0)
            side = user_side(d.label, False)
            smooth = smooth or OneEuro()
            times.append(n / fps)
            raw.append(geometry.leap_hand(points, side, 1, 1.0)["palm_position"])
            filtered.append(geometry.leap_hand(smooth(points, n / fps), side, 1, 1.0)[
                "palm_position"])
        n += 1
    tracker.close()
    return np.asarray(times), np.asarray(raw), np.asarray(filtered)


def smoothing_figures(still: Path, moving: Path, complexity: int) -> dict:
    """Figure 6: jitter of a still hand and lag of a moving one, raw and filtered."""
    out = {}
    for name, video in (("still", still), ("moving", moving)):
        t, raw, filtered = palm_paths(video, complexity)
        for kind, path in (("raw", raw), ("filtered", filtered)):
            steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
            speed = steps / np.diff(t)
            out[name, kind] = {"step_p50": np.percentile(steps, 50),
                               "step_p95": np.percentile(steps, 95),
                               "travel": np.linalg.norm(path[-1] - path[0]),
                               "speed_p90": np.percentile(speed, 90)}
        out[name, "lag"] = {"mean_mm": float(np.linalg.norm(filtered - raw, axis=1).mean()),
                            "frames": len(t)}
    return out


def turned_palm_down(hand: dict) -> dict:
    """Returns the same hand turned about its palm centre to how a Leap user holds it.

    Palm down, fingers pointing away from the user, 200 mm above the sensor.
    """
    from cbgo.services.camera_bridge import geometry

    d, n = np.asarray(hand["direction"]), np.asarray(hand["palm_normal"])
    forward, down = np.array([0.0, 0.0, -1.0]), np.array([0.0, -1.0, 0.0])
    rotation = np.stack([forward, down, np.cross(forward, down)]).T @ np.stack(
        [d, n, np.cross(d, n)])
    points = geometry.landmarks_from_hand(hand) - np.asarray(hand["palm_position"])
    return geometry.leap_hand(points @ rotation.T + [0.0, 200.0, 0.0], hand["side"],
                              hand["id"], hand["confidence"])


def orientation_readings(labelled: dict[str, list[Path]], complexity: int) -> list[tuple]:
    """Figure 7: the static model on each item's camera hands as seen and turned palm down.

    In-process (`StaticClassifier.classify_hands`, the service's model): how much of an answer
    comes from the hand's pose and how much from the way it is turned towards the camera.
    Returns (label, file name, Counter as seen, Counter turned).
    """
    from cbgo.services.static_gesture.classifier import StaticClassifier, default_model_path

    model = StaticClassifier.load(default_model_path())
    out = []
    for label, files in labelled.items():
        for f in files:
            hands = camera_hands([f], complexity)
            if not hands:
                continue
            seen = model.classify_hands(hands)
            turned = model.classify_hands([turned_palm_down(h) for h in hands])
            out.append((label, f.name,
                        Counter(model.names[int(k)] for k in seen.argmax(1)),
                        Counter(model.names[int(k)] for k in turned.argmax(1))))
    return out


def feature_comparison(label: str, files: list[Path], complexity: int) -> list[tuple]:
    """Figure 5: the static model's device-independent features of one pose, side by side.

    The real Leap recordings of the pose (`cbgo.hands.data`), simulated Leap hands of it (the
    calibrated pose, 200 people), and camera-bridge's hands of the labelled files; each on the
    recordings' side, through `invariant.derive` (the 45 features every Leap-style tracker
    reports alike). Returns (name, real mean, real sd, simulated mean, camera median, z).
    """
    from cbgo.hands.data import load_real_features
    from cbgo.hands.features import hand_features
    from cbgo.hands.model import HandShape, build_hand
    from cbgo.hands.poses import gesture_pose
    from cbgo.services.static_gesture import invariant

    x, y, names = load_real_features()
    real = invariant.derive(x[y == names.index(label)])
    rng = np.random.default_rng(0)
    simulated = invariant.derive(np.stack([hand_features(build_hand(
        HandShape.sample(rng, side=str(rng.choice(["left", "right"]))),
        gesture_pose(label, rng), (0.0, 200.0, 0.0)), to_recorded_side=True)
        for _ in range(200)]))
    camera = invariant.derive(np.stack([hand_features(h, to_recorded_side=True)
                                        for h in camera_hands(files, complexity)]))
    out = []
    for k, name in enumerate(invariant.NAMES):
        mean, sd = real[:, k].mean(), real[:, k].std() + 1e-9
        cam = np.median(camera[:, k])
        out.append((name, mean, sd, simulated[:, k].mean(), cam, (cam - mean) / sd,
                    len(camera)))
    return out


def per_frame_time(video: Path, complexity: int) -> dict:
    """Figure 3: MediaPipe + geometry per frame, in this process."""
    import cv2

    from cbgo.services.camera_bridge import geometry
    from cbgo.services.camera_bridge.main import user_side
    from cbgo.services.camera_bridge.tracker import HandTracker

    capture = cv2.VideoCapture(str(video))
    images = []
    while True:
        ok, image = capture.read()
        if not ok:
            break
        images.append(image)
    tracker, pose = HandTracker(model_complexity=complexity), geometry.CameraPose()
    wall, cpu, tracking = [], [], []
    for image in images:
        t0, c0 = time.perf_counter(), time.process_time()
        height, width = image.shape[:2]
        K = geometry.camera_matrix(width, height)
        detections = tracker.detect(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        tracking.append((time.process_time() - c0) * 1e3)
        for d in detections[:1]:
            shift = geometry.solve_translation(d.world_m, d.image_px, K)
            points = pose.to_leap((d.world_m + shift) * 1000.0)
            geometry.leap_hand(points, user_side(d.label, False), 1, d.score)
        wall.append((time.perf_counter() - t0) * 1e3)
        cpu.append((time.process_time() - c0) * 1e3)
    return {"size": f"{images[0].shape[1]}x{images[0].shape[0]}", "frames": len(images),
            "wall_p50": np.percentile(wall, 50), "wall_p95": np.percentile(wall, 95),
            "cpu_p50": np.percentile(cpu, 50), "cpu_p95": np.percentile(cpu, 95),
            "mediapipe_cpu_p50": np.percentile(tracking, 50)}


def cpu_at_30fps(video: Path, seconds: float, complexity: int) -> dict:
    """Figure 4: camera-bridge as a process on a video played at 30 fps."""
    import cv2

    from cbgo.testing import Stack

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        looped = Path(tmp) / "at30.mp4"
        source = cv2.VideoCapture(str(video))
        ok, image = source.read()
        writer = cv2.VideoWriter(str(looped), cv2.VideoWriter_fourcc(*"mp4v"), 30.0,
                                 (image.shape[1], image.shape[0]))
        while ok:
            writer.write(image)
            ok, image = source.read()
        writer.release()
        stack.start_router()
        stack.wait_alive(["router"])
        bridge = stack.start_service("camera-bridge", "--camera", str(looped), "--loop",
                                     "--model-complexity", str(complexity))
        stack.wait_alive(["camera-bridge"], timeout=START_S)
        time.sleep(2.0)  # past the start
        before, t0 = _cpu_seconds(bridge.popen.pid), time.monotonic()
        start = stack.status("camera-bridge")["reading"]
        time.sleep(seconds)
        after, t1 = _cpu_seconds(bridge.popen.pid), time.monotonic()
        end = stack.status("camera-bridge")
    read = end["reading"]["read"] - start["read"]
    dropped = end["reading"]["dropped"] - start["dropped"]
    return {"cpu_percent": 100.0 * (after - before) / (t1 - t0), "read": read,
            "dropped": dropped, "fps_processed": read / (t1 - t0),
            "frame_time": end["frame_time"]}


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process and its threads (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(args: argparse.Namespace) -> int:
    """Measures and prints every figure."""
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; MediaPipe "
          f"model_complexity {args.model_complexity}", flush=True)
    rows, latencies = accuracy(args.data, args.hold_s, args.model_complexity)
    print("\n1. per item, through camera-bridge and static-gesture (live processes)")
    print(f"{'label':<12} {'item':<28} {'frames':>7} {'answered':>9} {'score':>7}  answers")
    for row in rows:
        kind = "right" if row["in_vocabulary"] else "rejected"
        answers = ", ".join(f"{k} {v}" for k, v in row["answers"].most_common(4))
        print(f"{row['label']:<12} {row['name'][:28]:<28} {row['shown']:>7} "
              f"{row['answered']:>9} {row['score']:>6.0%}  {kind}; {answers}")
    by_label = defaultdict(list)
    for row in rows:
        by_label[row["label"]].append(row)
    print("\nper class (frames pooled over its items)")
    for label, group in by_label.items():
        shown = sum(r["shown"] for r in group)
        good = sum(r["good"] for r in group)
        what = "accuracy" if group[0]["in_vocabulary"] else "rejected (none or p < 0.5)"
        print(f"  {label:<12} {what}: {good / max(shown, 1):.1%} of {shown} frames")
    if latencies:
        print(f"\n2. frame captured -> gestures/static arrived: p50 "
              f"{np.percentile(latencies, 50):.0f} ms, p95 {np.percentile(latencies, 95):.0f} "
              f"ms ({len(latencies)} frames)")
    speed = per_frame_time(args.speed_video, args.model_complexity)
    print(f"\n3. bridge per frame ({speed['size']}, {speed['frames']} frames, in-process): "
          f"wall p50 {speed['wall_p50']:.1f} ms, p95 {speed['wall_p95']:.1f} ms; CPU p50 "
          f"{speed['cpu_p50']:.1f} ms, p95 {speed['cpu_p95']:.1f} ms (of it MediaPipe's "
          f"tracking: CPU p50 {speed['mediapipe_cpu_p50']:.1f} ms)")
    cpu = cpu_at_30fps(args.speed_video, args.seconds, args.model_complexity)
    print(f"\n4. camera-bridge process at 30 fps for {args.seconds:.0f} s: CPU "
          f"{cpu['cpu_percent']:.0f} % of one core; processed {cpu['fps_processed']:.1f} "
          f"frames/s, skipped {cpu['dropped']} of {cpu['read'] + cpu['dropped']} to keep up; "
          f"its frame time p50 {cpu['frame_time'].get('p50_ms', float('nan')):.1f} ms")
    labelled = labelled_items(args.data)
    if "thumbsup" in labelled:
        table = feature_comparison("thumbsup", labelled["thumbsup"], args.model_complexity)
        z = np.array([row[5] for row in table])
        print(f"\n5. thumbsup: the static model's 45 device-independent features, real Leap "
              f"recordings vs simulated Leap hands vs camera-bridge ({table[0][6]} camera "
              "hands, median); z = (camera - real mean) / real sd")
        print(f"   {np.mean(np.abs(z) < 1):.0%} of features within 1 sd of the real Leap "
              f"hands, {np.mean(np.abs(z) < 2):.0%} within 2 sd; median |z| "
              f"{np.median(np.abs(z)):.2f}")
        print(f"   {'feature':<34} {'real mean':>10} {'real sd':>8} {'sim mean':>9} "
              f"{'camera':>8} {'z':>6}")
        for name, mean, sd, sim, cam, zk, _ in table:
            print(f"   {name:<34} {mean:>10.2f} {sd:>8.2f} {sim:>9.2f} {cam:>8.2f} {zk:>6.1f}")
    if args.data is None:
        smooth = smoothing_figures(FIXTURES / "thumbs_up_clip.mp4",
                                   FIXTURES / "open_palm_reaching.mp4", args.model_complexity)
        print("\n6. the landmark filter (One-Euro): palm step between frames p50 / p95 (mm), "
              "palm speed p90 (mm/s), and how far the filtered palm trails the raw one")
        for name, what in (("still", "thumbs-up held (thumbs_up_clip.mp4)"),
                           ("moving", "hand reaching out (open_palm_reaching.mp4)")):
            cells = "; ".join(
                f"{kind} {out['step_p50']:.1f} / {out['step_p95']:.1f} mm, "
                f"{out['speed_p90']:.0f} mm/s"
                for kind in ("raw", "filtered") for out in [smooth[name, kind]])
            print(f"   {what}: {cells}; filtered - raw {smooth[name, 'lag']['mean_mm']:.1f} "
                  f"mm mean over {smooth[name, 'lag']['frames']} frames")
    print("\n7. the static model on the camera hands as seen, and turned palm down with the "
          "fingers forward (as over a Leap), in-process")
    for label, name, seen, turned in orientation_readings(labelled, args.model_complexity):
        print(f"   {label:<12} {name[:28]:<28} seen: "
              + ", ".join(f"{k} {v}" for k, v in seen.most_common(3))
              + "; turned: " + ", ".join(f"{k} {v}" for k, v in turned.most_common(3)))
    return 0
