"""mujoco-sim: the Panda table-top world in MuJoCo; executes robot actions physically.

MuJoCo chooses its OpenGL platform when it is first imported, so the headless default
(``MUJOCO_GL=egl``) is set here, before any module of this package imports it; a value already
in the environment (``osmesa``, ``glfw``) is kept.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
