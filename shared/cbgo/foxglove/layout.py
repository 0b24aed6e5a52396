"""The Foxglove layout cbgo ships: 3D scene, gesture probabilities, intent confidence, log.

Built with the foxglove-sdk's layout API (`foxglove.layouts`), so the JSON is in the format
Foxglove imports (*Import layout*). The shipped copy is ``deploy/foxglove/layout.json``;
``make docs`` writes it again and the tests check the copy matches.

Panels: a 3D panel following the robot base frame with ``foxglove/scene`` and the frame
transforms; a plot of the static gesture probabilities (one series per class, in the order the
shipped static-gesture model names them) and one of the dynamic gestures; a plot of the intent
confidence; the log of ``foxglove/log``. cbgo's topics have no leading ``/`` (they are the Zenoh
keys), so message paths quote them: ``"cbgo/gestures/static".probs[0]``.
"""

from __future__ import annotations

import json

from cbgo import wire
from cbgo.foxglove.derive import LOG_TOPIC, SCENE_TOPIC, TRANSFORMS_TOPIC
from cbgo.foxglove.scene import BASE_FRAME

STATIC_NAMES = (*wire.STATIC_GESTURES, "none")  # the shipped model's classes, in its order
DYNAMIC_NAMES = (*wire.DYNAMIC_GESTURES, "none")


def _series(fl, topic: str, names: tuple[str, ...]) -> list:
    return [fl.PlotSeries(value=f'"{topic}".probs[{i}]', label=name, enabled=True,
                          timestamp_method="receiveTime") for i, name in enumerate(names)]


def _plot(fl, title: str, series: list):
    return fl.PlotPanel(title=title, config=fl.PlotConfig(
        paths=series, min_y_value=0.0, max_y_value=1.0, show_legend=True))


def build(prefix: str = "cbgo"):
    """Returns the layout as a `foxglove.layouts.Layout` (topics under `prefix`)."""
    import foxglove.layouts as fl

    scene = fl.ThreeDeePanel(title="cbgo scene (robot base frame)", config=fl.ThreeDeeConfig(
        follow_tf=BASE_FRAME, topics={SCENE_TOPIC: {"visible": True},
                                      TRANSFORMS_TOPIC: {"visible": True}}))
    plots = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=_plot(fl, "static gesture probabilities",
                                   _series(fl, f"{prefix}/gestures/static", STATIC_NAMES))),
        fl.SplitItem(content=_plot(fl, "dynamic gesture probabilities",
                                   _series(fl, f"{prefix}/gestures/dynamic", DYNAMIC_NAMES))),
        fl.SplitItem(content=_plot(fl, "intent confidence", [fl.PlotSeries(
            value=f'"{prefix}/intent".confidence', label="confidence", enabled=True)])),
    ])
    log = fl.LogPanel(title="episodes, intents, plans",
                      config=fl.LogConfig(topic_to_render=LOG_TOPIC, show_name=True))
    right = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(proportion=3, content=plots), fl.SplitItem(proportion=1, content=log)])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=3, content=scene), fl.SplitItem(proportion=2, content=right)]))


def layout_json(prefix: str = "cbgo") -> str:
    """Returns the layout as indented JSON text (what ``deploy/foxglove/layout.json`` holds)."""
    return json.dumps(json.loads(build(prefix).to_json()), indent=2) + "\n"
