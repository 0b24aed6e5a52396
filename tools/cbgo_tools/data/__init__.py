"""Real data sets for fitting and benchmarking: where each comes from, where it is cached.

None of them is committed (most have no licence file): ``cbgo data fetch NAME`` copies a set's
folder from its public repository into the cache (`cbgo.config.cache_dir`), ``cbgo data
convert NAME`` turns it into what the trainers and benches read, and ``cbgo data list`` shows
what is there. Which sets, and which parts of them, may be fitted on and which are kept for
checks is written in ``use``; the loaders enforce the splits (e.g. `cbgo_tools.data.shrec`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from cbgo.config import cache_dir


@dataclass(frozen=True)
class DataSet:
    """One public data set.

    Attributes:
        name: the name on the command line and the cache folder's name.
        summary: what it is, in one line.
        repo: the GitHub repository (owner/name) that holds a public copy.
        folder: the folder inside that repository.
        use: what may be fitted on, and what is only scored.
        commit: the commit to take it from, where the newest one no longer has it.
        converter: the module behind ``cbgo data convert NAME`` (``add_arguments``, ``run``),
            None when the benches read the fetched folder as it is.
    """

    name: str
    summary: str
    repo: str
    folder: str
    use: str
    commit: str | None = None
    converter: str | None = None

    @property
    def path(self) -> Path:
        """The fetched copy of ``folder``: ``<cache>/<name>``."""
        return cache_dir() / self.name


QUANTUMLEAP = "sluyters/QuantumLeap"
DATASETS: dict[str, DataSet] = {d.name: d for d in (
    DataSet("shrec17", "SHREC'17 / DHG-14/28: depth-camera hand skeletons, 28 people, 14 gestures",
            "giach68/gesturesCodes", "datasetShrec",
            "train split (train_gestures.txt): fit and tune; test split: reserved, never fitted"),
    DataSet("gesturemidair", "GestureMidAir: Leap fingertip paths of 13 people, 26 drawn gestures",
            "giach68/gesturesCodes", "datasetNew",
            "train people (train_gestures.txt): development; test people and davide: reserved"),
    DataSet("mmhgr", "HGR multi-modal Leap set: 25 people, 16 static poses, Leap SDK v2",
            QUANTUMLEAP, "backend/src/datasets/static/multi_mod_hand_gest_recog",
            "development (static-gesture training with people kept apart)",
            converter="cbgo_tools.data.mmhgr"),
    DataSet("guinevere", "Guinevere: LeapJS recordings of 4 people, 23 dynamic gestures",
            QUANTUMLEAP, "backend/src/datasets/dynamic/guinevere", "evaluation only"),
    DataSet("guinevere-static", "Guinevere's static poses: one person's LeapJS frames",
            QUANTUMLEAP, "backend/src/datasets/static/guinevre-static2", "evaluation only",
            converter="cbgo_tools.data.guinevere"),
    DataSet("leapmotion-all", "16 people's own previous/next swipes, either hand (LeapJS)",
            QUANTUMLEAP, "backend/src/datasets/dynamic/leapmotion-all", "evaluation only",
            commit="bec964af", converter="cbgo_tools.data.leapjs"),
    DataSet("collaborice", "CollaborICE: Leap Motion Controller 2 (LeapC, Gemini) right hands, "
            "2 people, 4 static poses, JSON lines",
            "univr-GRAIL/CollaborICE_Leap_Gesture_Recognition",
            "gesture_recognizer_creator/data/train",
            "development (its train folder, people kept apart); the repository's test folder "
            "is reserved: never fetched, never read", converter="cbgo_tools.data.collaborice"),
)}
