"""Builds the MuJoCo world of one symbolic scene with MjSpec: Panda, table, cups, boxes, drawers.

Rules:
- the robot base frame is MuJoCo's world frame: +x away from the robot, +z up, table top z = 0;
- an object's contract ``position`` is its geometric centre; its ``size`` is a cup's height,
  a box's edge, a drawer cabinet's edge (drawers are cubes that open along x towards the
  middle of the table, as `cbgo.world.scene.drawer_direction` says: a cabinet that opens away
  from the robot is the same cabinet turned by 180° about z);
- objects are placed where the scene says in x/y, and in z on what they stand on (``on``,
  ``inside``, the table), so nothing starts interpenetrating; the caller settles the physics;
- every movable object (and each drawer) gets an inactive weld to the hand, switched on only
  after a verified grasp (``engine.Sim.attach``);
- the Panda is the vendored MuJoCo Menagerie model, with the changes measured to make friction
  grasps hold: elliptic friction cones, ``impratio`` 10, a 10x stiffer finger actuator and
  gravity compensation of the arm.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from cbgo.world.scene import DRAWER_FLOOR, drawer_direction
from cbgo.world.workspace import DRAWER_HANDLE_OUT, DRAWER_TRAVEL_PER_SIZE

PANDA_XML = Path(__file__).parent / "assets" / "franka_emika_panda" / "panda.xml"
ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("finger_joint1", "finger_joint2")
ARM_BODIES = ("link1", "link2", "link3", "link4", "link5", "link6", "link7", "hand",
              "left_finger", "right_finger")
HOME_Q = np.array([0.0, -0.35, 0.0, -2.25, 0.0, 1.9, math.pi / 4])
TCP_OFFSET = 0.103  # hand origin -> centre of the finger pads, m
FINGER_OPEN = 0.04  # per finger, m
PAD_INSET = 0.0015  # pad face at finger q + PAD_INSET from the hand's mid plane
TIMESTEP = 0.005
ROBOT_BIT, OBJECT_BITS = 2, 3  # contype of robot geoms; conaffinity of object geoms
WALL = 0.004  # drawer and cabinet wall thickness, m

CUP_COLORS = ((0.85, 0.25, 0.2), (0.95, 0.75, 0.2), (0.55, 0.3, 0.75), (0.9, 0.5, 0.15))
BOX_COLORS = ((0.2, 0.6, 0.3), (0.25, 0.45, 0.85), (0.8, 0.35, 0.55), (0.35, 0.7, 0.7))
WOOD = (0.62, 0.45, 0.3, 1.0)
WOOD_DARK = (0.5, 0.35, 0.22, 1.0)
LIQUID = (0.15, 0.45, 0.95, 1.0)
EMPTY = (0.2, 0.18, 0.17, 1.0)


# ------------------------------------------------------------------------- object geometry


@dataclass(frozen=True)
class CupDims:
    """A cup: a solid collision cylinder (the liquid is a simulated boolean)."""

    radius: float
    height: float

    @classmethod
    def of(cls, size: float) -> CupDims:
        """Returns the cup of a contract size (its height)."""
        return cls(radius=min(0.03, 0.4 * size), height=size)

    @property
    def half_height(self) -> float:
        """Half the height, m."""
        return self.height / 2


@dataclass(frozen=True)
class BoxDims:
    """A cube."""

    edge: float

    @property
    def half_height(self) -> float:
        """Half the edge, m."""
        return self.edge / 2


@dataclass(frozen=True)
class DrawerDims:
    """A cubic cabinet (edge ``size``) with one drawer (a tray) sliding out of its front.

    Frames: the cabinet's origin is the centre of its base on the table, its front face at
    -x of its own frame (the world's -x for a drawer that opens towards the robot; the
    cabinet is turned by 180° about z for one that opens away from it); the tray's frame
    coincides with it when the drawer is closed and slides by ``q`` in [0, travel] along its
    -x. The tray's floor is `DRAWER_FLOOR` above the table, as the world model says.
    Coordinates below are in those frames.
    """

    size: float

    @property
    def travel(self) -> float:
        """How far the tray slides out, m (0.09 for the default 0.11 cabinet)."""
        return round(DRAWER_TRAVEL_PER_SIZE * self.size, 4)

    @property
    def gap(self) -> float:
        """Clearance between the tray and the cabinet, m."""
        return 0.002

    @property
    def floor_top(self) -> float:
        """Height of the tray's floor above the table, m."""
        return DRAWER_FLOOR

    @property
    def tray_half_y(self) -> float:
        """Half the tray's outer width, m."""
        return self.size / 2 - WALL - self.gap

    @property
    def inner_half_y(self) -> float:
        """Half the tray's inner width, m."""
        return self.tray_half_y - WALL

    @property
    def tray_x(self) -> tuple[float, float]:
        """The tray's outer x range in the tray frame (its front face is the cabinet's)."""
        return -self.size / 2, self.size / 2 - WALL - self.gap

    @property
    def inner_x(self) -> tuple[float, float]:
        """The tray's inner x range in the tray frame."""
        x0, x1 = self.tray_x
        return x0 + WALL, x1 - WALL

    @property
    def wall_top(self) -> float:
        """Height of the tray's side and back walls above the table, m."""
        return self.floor_top + 0.4 * self.size

    @property
    def spot_x(self) -> float:
        """Where an object goes in the tray (x in the tray frame).

        The middle of the part that is outside the cabinet when the drawer is open, so the
        hand stays clear of the cabinet.
        """
        return -self.size / 2 + (WALL + self.travel) / 2

    @property
    def handle(self) -> tuple[float, float, float]:
        """Grasp point of the handle knob in the tray frame."""
        return (-self.size / 2 - DRAWER_HANDLE_OUT, 0.0, self.size - 0.035)

    @property
    def half_height(self) -> float:
        """Half the cabinet height, m."""
        return self.size / 2


def dims_of(obj: dict) -> CupDims | BoxDims | DrawerDims:
    """Returns the geometry of a contract object."""
    kind, size = obj["type"], float(obj["size"])
    if kind == "cup":
        return CupDims.of(size)
    if kind == "box":
        return BoxDims(size)
    return DrawerDims(size)


# ------------------------------------------------------------------------- the built world


@dataclass
class Item:
    """One symbolic object in the compiled model."""

    name: str
    type: str
    size: float
    dims: CupDims | BoxDims | DrawerDims
    body: int = -1  # the movable body (cup, box, the drawer's sliding body)
    cabinet: int = -1  # drawers: the fixed cabinet body
    joint: int = -1  # free joint (cup, box) or slide joint (drawer)
    weld: int = -1  # the hand weld (inactive until a grasp is verified)
    liquid_geom: int = -1  # cups: the visual liquid surface
    bottom_geom: int = -1  # drawers: the inner bottom
    handle_geom: int = -1  # drawers: the handle knob
    geoms: frozenset[int] = frozenset()  # every collision geom of the object
    qpos: int = -1  # address of the object's joint in qpos
    direction: int = -1  # drawers: the way along the world's x their tray slides out


@dataclass
class Built:
    """A compiled world: model, data and where every object and robot part is."""

    model: mujoco.MjModel
    data: mujoco.MjData
    items: dict[str, Item]
    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    finger_qpos: np.ndarray
    finger_dof: np.ndarray
    tcp_site: int
    hand_body: int
    left_finger: int
    right_finger: int
    finger_geoms: dict[int, frozenset[int]] = field(default_factory=dict)
    table_geom: int = -1
    compile_s: float = 0.0


# ------------------------------------------------------------------------- MjSpec pieces


def _panda_spec() -> mujoco.MjSpec:
    spec = mujoco.MjSpec.from_file(str(PANDA_XML))
    for key in list(spec.keys):
        spec.delete(key)  # the home keyframe has the Panda's nq only
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10
    spec.option.timestep = TIMESTEP
    for name in ARM_BODIES:
        spec.body(name).gravcomp = 1.0
    for i in range(1, 8):
        # A clipped servo force no longer matches the velocity derivative the implicit
        # integrator uses, and the light wrist then chatters at the time step (measured: the
        # 12 N·m of joints 5-7 saturate at 6 mrad of error). Unclipped, the affine servo is
        # integrated exactly; planning keeps the arm out of collisions.
        spec.actuator(f"actuator{i}").forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    fingers = spec.actuator("actuator8")  # position servo on the finger tendon, in metres
    fingers.ctrlrange = [0.0, FINGER_OPEN]
    fingers.gainprm[0] = 1000.0
    fingers.biasprm[:3] = [0.0, -1000.0, -100.0]
    fingers.forcerange = [-200.0, 200.0]
    spec.body("hand").add_site(name="tcp", pos=[0, 0, TCP_OFFSET], size=[0.005] * 3,
                               rgba=[1, 0, 0, 0.0], group=4)
    spec.add_exclude(bodyname1="link0", bodyname2="link1")
    # Collision filtering, for speed: the robot (contype 2) touches the objects (conaffinity
    # 3) but not itself, and only its fingers touch the table (the arm never folds onto
    # itself or reaches below the fingertips in these motions; mesh-plane pairs of every link
    # with the table top were half the cost of collision detection).
    for geom in spec.geoms:
        if geom.contype or geom.conaffinity:
            geom.contype = ROBOT_BIT
            geom.conaffinity = 1 if geom.parent.name in ("left_finger", "right_finger") else 0
    spec.visual.global_.offwidth = 1920
    spec.visual.global_.offheight = 1440
    spec.visual.quality.shadowsize = 2048
    return spec


def _look_at(pos, target) -> list[float]:
    """Returns the quaternion of a camera at pos looking at target (+z of the world up)."""
    forward = np.asarray(target, float) - np.asarray(pos, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # looking straight down: the image's up is +x
        right = np.cross(forward, [1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    mat = np.column_stack([right, up, -forward])  # camera looks along its -z
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, mat.ravel())
    return quat.tolist()


CAMERAS = {
    # name: (position, look-at point)
    "overview": ((0.05, -0.8, 0.75), (0.5, 0.0, 0.05)),
    "workspace": ((0.2, -0.55, 0.5), (0.58, -0.03, 0.04)),
    "front": ((1.45, 0.0, 0.75), (0.45, 0.0, 0.05)),
    "side": ((0.5, -1.1, 0.45), (0.5, 0.0, 0.08)),
    "top": ((0.5, 0.0, 1.3), (0.5, 0.0, 0.0)),
    "robot": ((-0.35, 0.0, 0.75), (0.55, 0.0, 0.0)),
}


def _stage(spec: mujoco.MjSpec) -> None:
    world = spec.worldbody
    grid = spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                            rgb1=[0.82, 0.8, 0.76], rgb2=[0.76, 0.74, 0.7], width=256,
                            height=256)
    table_mat = spec.add_material(name="table", texrepeat=[8, 8])
    table_mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = grid.name
    # The table top collides as a plane (analytic contacts, cheaper than a box); the box is
    # what is seen.
    world.add_geom(name="table_top", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[0.35, 0.0, -0.025],
                   size=[0.8, 0.85, 0.025], material="table", contype=0, conaffinity=0)
    world.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, pos=[0.0, 0.0, 0.0],
                   size=[0, 0, 1], group=3, rgba=[0, 0, 0, 0])
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, pos=[0, 0, -0.75],
                   size=[4, 4, 0.1], rgba=[0.35, 0.37, 0.4, 1], contype=0, conaffinity=0)
    world.add_light(name="key", pos=[0.6, -0.6, 2.0], dir=[-0.1, 0.3, -1.0],
                    diffuse=[0.7, 0.7, 0.7], castshadow=True)
    world.add_light(name="fill", pos=[0.6, 0.8, 1.5], dir=[0.0, -0.5, -1.0],
                    diffuse=[0.35, 0.35, 0.35], castshadow=False)
    for name, (pos, target) in CAMERAS.items():
        world.add_camera(name=name, pos=list(pos), quat=_look_at(pos, target), fovy=50)


def _box(body, name: str, pos, half, rgba, **kw):
    kw.setdefault("conaffinity", OBJECT_BITS)
    return body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(pos),
                         size=list(half), rgba=list(rgba), **kw)


def _add_cup(spec: mujoco.MjSpec, item: Item, index: int) -> None:
    d: CupDims = item.dims
    rgb = CUP_COLORS[index % len(CUP_COLORS)]
    body = spec.worldbody.add_body(name=item.name)
    body.add_freejoint(name=f"{item.name}/joint")
    body.add_geom(name=f"{item.name}/collision", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                  size=[d.radius, d.half_height, 0], mass=0.15, group=3, conaffinity=OBJECT_BITS,
                  rgba=[*rgb, 1], friction=[1.0, 0.01, 0.001])
    # The visual shell: a wall, a rim and the inside, which shows the liquid when full.
    visual = dict(contype=0, conaffinity=0, group=2, mass=0)
    body.add_geom(name=f"{item.name}/shell", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                  size=[d.radius, d.half_height - 0.002, 0], pos=[0, 0, -0.002],
                  rgba=[*rgb, 1], **visual)
    body.add_geom(name=f"{item.name}/rim", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                  size=[d.radius, 0.002, 0], pos=[0, 0, d.half_height - 0.002],
                  rgba=[0.95, 0.95, 0.95, 1], **visual)
    body.add_geom(name=f"{item.name}/liquid", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                  size=[d.radius - 0.004, 0.0025, 0], pos=[0, 0, d.half_height - 0.0015],
                  rgba=list(EMPTY), **visual)


def _add_box(spec: mujoco.MjSpec, item: Item, index: int) -> None:
    d: BoxDims = item.dims
    rgb = BOX_COLORS[index % len(BOX_COLORS)]
    body = spec.worldbody.add_body(name=item.name)
    body.add_freejoint(name=f"{item.name}/joint")
    _box(body, f"{item.name}/collision", [0, 0, 0], [d.edge / 2] * 3, [*rgb, 1], mass=0.12,
         friction=[1.0, 0.01, 0.001])


def _add_drawer(spec: mujoco.MjSpec, item: Item, xy) -> None:
    d: DrawerDims = item.dims
    s, t, n = d.size, WALL, item.name
    turned = [1.0, 0.0, 0.0, 0.0] if item.direction < 0 else [0.0, 0.0, 0.0, 1.0]
    cab = spec.worldbody.add_body(name=f"{n}/cabinet", pos=[xy[0], xy[1], 0.0], quat=turned)
    _box(cab, f"{n}/cab_bottom", [0, 0, t / 2], [s / 2, s / 2, t / 2], WOOD)
    _box(cab, f"{n}/cab_top", [0, 0, s - t / 2], [s / 2, s / 2, t / 2], WOOD)
    for side in (-1, 1):
        _box(cab, f"{n}/cab_side{side:+d}", [0, side * (s / 2 - t / 2), s / 2],
             [s / 2, t / 2, s / 2 - t], WOOD)
    _box(cab, f"{n}/cab_back", [s / 2 - t / 2, 0, s / 2], [t / 2, s / 2 - t, s / 2 - t], WOOD)
    tray = cab.add_body(name=n)
    tray.add_joint(name=f"{n}/slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[-1, 0, 0],
                   range=[0.0, d.travel], damping=8.0, frictionloss=0.3, armature=0.05)
    x0, x1 = d.tray_x
    hy = d.tray_half_y
    floor0 = d.floor_top - 0.005  # the floor plate is 5 mm thick
    _box(tray, f"{n}/bottom", [(x0 + x1) / 2, 0, floor0 + 0.0025], [(x1 - x0) / 2, hy, 0.0025],
         WOOD_DARK, mass=0.2)
    front_top = s - t - 0.002
    _box(tray, f"{n}/front", [x0 + t / 2, 0, (floor0 + front_top) / 2],
         [t / 2, hy, (front_top - floor0) / 2], WOOD, mass=0.05)
    wall_half = (d.wall_top - floor0) / 2
    _box(tray, f"{n}/back", [x1 - t / 2, 0, floor0 + wall_half], [t / 2, hy, wall_half],
         WOOD_DARK, mass=0.03)
    for side in (-1, 1):
        _box(tray, f"{n}/side{side:+d}", [(x0 + x1) / 2, side * (hy - t / 2), floor0 + wall_half],
             [(x1 - x0) / 2, t / 2, wall_half], WOOD_DARK, mass=0.03)
    _, _, hz = d.handle
    _box(tray, f"{n}/handle", [x0 - 0.015, 0, hz], [0.015, 0.012, 0.008],
         (0.25, 0.25, 0.27, 1), mass=0.02, friction=[1.2, 0.01, 0.001])


def _add_weld(spec: mujoco.MjSpec, body_name: str) -> None:
    spec.add_equality(name=f"grasp/{body_name}", type=mujoco.mjtEq.mjEQ_WELD,
                      objtype=mujoco.mjtObj.mjOBJ_BODY, name1="hand", name2=body_name,
                      active=False, solref=[0.01, 1.0])


def add_grid_markers(spec: mujoco.MjSpec, points) -> None:
    """Adds small yellow dots on the table at the grid's floor cells (visual only)."""
    for i, (x, y) in enumerate(points):
        spec.worldbody.add_geom(name=f"grid/{i}", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                                pos=[x, y, 0.0005], size=[0.006, 0.0005, 0],
                                rgba=[0.95, 0.85, 0.1, 1], contype=0, conaffinity=0, group=1)


# ------------------------------------------------------------------------- build


def build(objects: list[dict], grid_points=()) -> Built:
    """Compiles the world of a list of contract objects (`scenes.load` then places them).

    Args:
        objects: contract scene objects (name, type, size, position, ...).
        grid_points: (x, y) of grid cells to mark on the table.

    Returns:
        The compiled world with every object's handles, robot at rest, objects at the origin.
    """
    spec = _panda_spec()
    _stage(spec)
    add_grid_markers(spec, grid_points)
    items: dict[str, Item] = {}
    counts = {"cup": 0, "box": 0, "drawer": 0}
    for obj in objects:
        item = Item(obj["name"], obj["type"], float(obj["size"]), dims_of(obj))
        items[item.name] = item
        if item.type == "cup":
            _add_cup(spec, item, counts["cup"])
        elif item.type == "box":
            _add_box(spec, item, counts["box"])
        else:
            item.direction = drawer_direction(obj["position"][0])
            _add_drawer(spec, item, obj["position"][:2])
        counts[item.type] += 1
        _add_weld(spec, item.name)
    t0 = time.perf_counter()
    model = spec.compile()
    compile_s = time.perf_counter() - t0
    data = mujoco.MjData(model)
    built = Built(
        model=model, data=data, items=items,
        arm_qpos=np.array([model.jnt_qposadr[model.joint(j).id] for j in ARM_JOINTS]),
        arm_dof=np.array([model.jnt_dofadr[model.joint(j).id] for j in ARM_JOINTS]),
        finger_qpos=np.array([model.jnt_qposadr[model.joint(j).id] for j in FINGER_JOINTS]),
        finger_dof=np.array([model.jnt_dofadr[model.joint(j).id] for j in FINGER_JOINTS]),
        tcp_site=model.site("tcp").id, hand_body=model.body("hand").id,
        left_finger=model.body("left_finger").id, right_finger=model.body("right_finger").id,
        table_geom=model.geom("table").id, compile_s=compile_s,
    )
    _resolve_handles(built)
    return built


def _geoms_of(model: mujoco.MjModel, bodies: set[int]) -> frozenset[int]:
    return frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies
                     and (model.geom_contype[g] or model.geom_conaffinity[g]))


def _resolve_handles(built: Built) -> None:
    m = built.model
    for item in built.items.values():
        item.body = m.body(item.name).id
        item.weld = m.equality(f"grasp/{item.name}").id
        if item.type == "drawer":
            item.cabinet = m.body(f"{item.name}/cabinet").id
            item.joint = m.joint(f"{item.name}/slide").id
            item.bottom_geom = m.geom(f"{item.name}/bottom").id
            item.handle_geom = m.geom(f"{item.name}/handle").id
            item.geoms = _geoms_of(m, {item.body, item.cabinet})
        else:
            item.joint = m.joint(f"{item.name}/joint").id
            item.geoms = _geoms_of(m, {item.body})
            if item.type == "cup":
                item.liquid_geom = m.geom(f"{item.name}/liquid").id
        item.qpos = int(m.jnt_qposadr[item.joint])
    built.finger_geoms = {b: _geoms_of(m, {b}) for b in (built.left_finger, built.right_finger)}
