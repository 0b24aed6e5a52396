"""franka's time limits run on the robot's own clock (a busy simulator's runs slow)."""

import pytest

from cbgo.services.franka import arm
from cbgo.services.franka.arm import ArmFault, RobotClock


class Clocks:
    """The robot's clock and the wall clock, moved by hand."""

    def __init__(self):
        self.robot, self.wall = 100.0, 5000.0


@pytest.fixture
def clocks(monkeypatch):
    c = Clocks()
    monkeypatch.setattr(arm.time, "monotonic", lambda: c.wall)
    return c


def test_a_command_is_overdue_after_its_limit_of_robot_time_not_of_wall_time(clocks):
    clock = RobotClock(lambda: clocks.robot, 60.0)
    for _ in range(100):  # 100 s of wall time, 50 s of a slow simulator's time: still running
        clocks.wall += 1.0
        clocks.robot += 0.5
        clock.check("the motion")
    clocks.robot += 10.5
    with pytest.raises(ArmFault) as fault:
        clock.check("the motion")
    assert fault.value.kind == "planner" and "60 s of the robot's time" in str(fault.value)


def test_a_clock_that_stands_still_is_a_lost_robot(clocks):
    clock = RobotClock(lambda: clocks.robot, 60.0)
    clocks.wall += arm.CLOCK_STALL_S - 1.0
    clock.check("the motion")  # not yet
    clocks.wall += 2.0
    with pytest.raises(ArmFault) as fault:
        clock.check("the motion")
    assert fault.value.kind == "connection" and "clock has not moved" in str(fault.value)


def test_an_overdue_gripper_command_is_a_gripper_fault(clocks):
    clock = RobotClock(lambda: clocks.robot, 10.0, overdue="gripper")
    clocks.robot += 10.5
    with pytest.raises(ArmFault) as fault:
        clock.check("grasping 0.050 m")
    assert fault.value.kind == "gripper" and "10 s of the robot's time" in str(fault.value)
