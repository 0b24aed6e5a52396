"""Hand-built scenes for the world-model tests."""

from cbgo.world import DEFAULT_GRID, Robot, Scene, SceneObject
from cbgo.world.scene import DEFAULT_SIZES


def obj(name, kind, column=(1, 1), **fields):
    x, y = DEFAULT_GRID.column_xy(column)
    size = DEFAULT_SIZES[kind]
    return SceneObject(name, kind, (x, y, size / 2), size, **fields)


def world(*objects, tcp_cell=(1, 1, 3), holding=None):
    scene = Scene(list(objects), Robot(DEFAULT_GRID.position(tcp_cell), holding is None,
                                       holding))
    scene.settle()
    assert scene.problems() == [], scene.problems()
    return scene
