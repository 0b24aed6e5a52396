"""Template files: the shipped default library and the gestures users teach, as JSON (no pickles).

- The default library is ``models/default.json`` in this package (``cbgo train dynamic
  --out`` writes it; plain ``cbgo train dynamic`` writes
  ``<data_dir>/models/dynamic-gesture.json``, which then stands in for it): the templates of
  ``swipe_up, swipe_down, swipe_left, swipe_right, rotate``, the calibration weights shared
  by all templates, the trajectory network that gives the shipped gestures a second opinion
  (``trajectory_net``, `trajnet`; a library without it uses the templates alone), the
  observation settings they were learned with, and a summary of the training run. Each
  default template names its mirror image (``mirror``: swipe_left's is
  swipe_right): they are learned in the right hand's space, and a left hand's strokes are
  matched mirrored (`classifier.mirror_rows`). A library without the field matches every
  stroke as performed.
- A user's gesture is one file ``<data_dir>/gestures/dynamic/<NAME>.json`` (`cbgo.config.data_dir`,
  ``CBGO_DATA_DIR``), written by ``cbgo gestures record NAME --dynamic``. It holds one template.
  A user template with the name of a default one replaces it (a personal version).
- `Library.load` reads both; `Library.changed` tells whether the user folder changed since
  (file names and modification times), which the service polls to reload by itself.
  A malformed user file is skipped with a reason (one bad file must not take the others down);
  a malformed default library is an error.
"""

from __future__ import annotations

import json
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

from cbgo.errors import ConfigError
from cbgo.services.dynamic_gesture.classifier import (
    NONE,
    Calibration,
    Classifier,
    NeuralCalibration,
    Template,
    calibration_from_dict,
)
from cbgo.services.dynamic_gesture.trajnet import TrajectoryNet

FORMAT = "cbgo-dynamic-gestures"
USER_FORMAT = "cbgo-dynamic-gesture"
VERSION = 1
DEFAULT_PATH = Path(__file__).parent / "models" / "default.json"
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")


def check_name(name: str) -> str:
    """Returns a gesture name if it is usable on the wire and as a file name.

    Raises:
        ConfigError: with what a valid name looks like.
    """
    if not NAME.match(name or "") or name == NONE:
        raise ConfigError(f"gesture name {name!r} is not valid: use letters, digits, '_', '.', "
                          f"'-' (up to 64, not {NONE!r}), e.g. 'swipe_diag'")
    return name


def trained_path(data_dir: Path) -> Path:
    """Returns where `cbgo train dynamic` writes: ``<data_dir>/models/dynamic-gesture.json``.

    The service uses it in place of the shipped one when it exists (never the package itself:
    an installed package may be read-only).
    """
    return Path(data_dir) / "models" / "dynamic-gesture.json"


def user_dir(data_dir: Path) -> Path:
    """Returns the folder of user-taught dynamic gestures under a data directory."""
    return Path(data_dir) / "gestures" / "dynamic"


def save_default(path: Path, templates: list[Template],
                 calibration: Calibration | NeuralCalibration,
                 observation: dict, training: dict, net: TrajectoryNet | None = None) -> None:
    """Writes the default library (atomically: a reader never sees half a file)."""
    data = {"format": FORMAT, "version": VERSION, "observation": observation,
            "calibration": calibration.to_dict(),
            "templates": [t.to_dict() for t in templates], "training": training}
    if net is not None:
        data["trajectory_net"] = net.to_dict()
    _write_json(Path(path), data)


def save_user_template(folder: Path, template: Template, takes: list[dict] | None = None
                       ) -> Path:
    """Writes one user template as ``<folder>/<name>.json``; returns the path.

    Args:
        folder: the user gesture folder.
        template: the learned template.
        takes: the demonstrations it was learned from (`take_record`), kept so that a later
            recording of the same name can add to them.
    """
    check_name(template.name)
    path = Path(folder) / f"{template.name}.json"
    _write_json(path, {"format": USER_FORMAT, "version": VERSION,
                       "template": template.to_dict(), "takes": takes or []})
    return path


def take_record(obs, duration_s: float, pose_change: float, user: str | None) -> dict:
    """Returns one demonstration as plain data (stored with a user template)."""
    return {"obs": [[round(float(v), 3) for v in row] for row in obs],
            "duration_s": float(duration_s), "pose_change": float(pose_change), "user": user,
            "recorded": time.time()}


def read_takes(path: Path) -> list[dict]:
    """Returns the demonstrations stored in a user file ([] if none or unreadable)."""
    try:
        takes = json.loads(Path(path).read_text()).get("takes") or []
    except (OSError, ValueError, AttributeError):
        return []
    return [t for t in takes if isinstance(t, dict) and isinstance(t.get("obs"), list)]


def _write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + f".tmp{os.getpid()}")
    tmp.write_text(json.dumps(data, separators=(",", ":")))
    tmp.replace(path)


def read_default(path: Path = DEFAULT_PATH
                 ) -> tuple[list[Template], Calibration | NeuralCalibration, dict]:
    """Returns (templates, calibration, the whole file as data) of a default library.

    Raises:
        ConfigError: missing or malformed file, naming the fix.
    """
    try:
        data = json.loads(Path(path).read_text())
        if data.get("format") != FORMAT or int(data.get("version", 0)) > VERSION:
            raise ValueError(f"not a {FORMAT} file of version <= {VERSION}")
        templates = [Template.from_dict(t) for t in data["templates"]]
        if "trajectory_net" in data:
            TrajectoryNet.from_dict(data["trajectory_net"])  # fails here, not in the service
        return templates, calibration_from_dict(data["calibration"]), data
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ConfigError(f"cannot load the dynamic-gesture templates {path} ({e}); run "
                          "`cbgo train dynamic` to create them") from None


def read_user_template(path: Path) -> Template:
    """Returns the template of one user file.

    Raises:
        ValueError: unreadable or malformed.
    """
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(str(e)) from None
    if not isinstance(data, dict) or data.get("format") != USER_FORMAT:
        raise ValueError(f"not a {USER_FORMAT} file")
    template = Template.from_dict(data.get("template") or {})
    check_name(template.name)
    if template.name != Path(path).stem:
        raise ValueError(f"holds gesture {template.name!r}, not {Path(path).stem!r}")
    return template


@dataclass
class Library:
    """The templates in use: the defaults plus the user's, and where they came from.

    Attributes:
        default_path: the default library file.
        user_folder: the folder of user templates (None: defaults only).
        templates: the loaded templates, defaults first, in a stable order.
        calibration: the shared calibration of the default library.
        net: the default library's trajectory network (None: it has none).
        replaced: the default gestures a user template replaced (the network's opinion on
            them is left out: it learned the shipped version).
        skipped: user files that could not be loaded, with the reason.
    """

    default_path: Path
    user_folder: Path | None
    templates: list[Template] = field(default_factory=list)
    calibration: Calibration | NeuralCalibration = field(default_factory=Calibration)
    net: TrajectoryNet | None = None
    replaced: set[str] = field(default_factory=set)
    skipped: dict[str, str] = field(default_factory=dict)
    _stamp: tuple = ()

    def load(self) -> Library:
        """(Re)reads every file; returns self.

        Raises:
            ConfigError: the default library is missing or malformed.
        """
        templates, self.calibration, data = read_default(self.default_path)
        net = data.get("trajectory_net")
        self.net = None if net is None else TrajectoryNet.from_dict(net)
        by_name = {t.name: t for t in templates}
        self.skipped = {}
        self._stamp = self._scan()
        for path in self._files():
            try:
                template = read_user_template(path)
            except (ValueError, ConfigError) as e:
                self.skipped[path.name] = str(e)
                continue
            by_name[template.name] = template
        self.templates = list(by_name.values())
        self.replaced = {t.name for t in templates if by_name[t.name] is not t}
        return self

    def _files(self) -> list[Path]:
        if self.user_folder is None or not Path(self.user_folder).is_dir():
            return []
        return sorted(Path(self.user_folder).glob("*.json"))

    def _scan(self) -> tuple:
        stamp = []
        for path in self._files():
            try:
                stamp.append((path.name, path.stat().st_mtime_ns))
            except OSError:
                continue  # removed while scanning: the next scan sees it gone
        return tuple(stamp)

    def changed(self) -> bool:
        """Returns whether user files were added, changed or removed since the last load."""
        return self._scan() != self._stamp

    def classifier(self, dtw: str = "exact") -> Classifier:
        """Returns a classifier over the loaded templates."""
        known = {t.name for t in self.templates} - self.replaced
        return Classifier(self.templates, self.calibration, dtw, self.net, known)

    @property
    def names(self) -> list[str]:
        """The gesture names, in order."""
        return [t.name for t in self.templates]
