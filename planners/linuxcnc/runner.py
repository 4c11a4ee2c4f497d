"""Run a G-code program on the real LinuxCNC 2.9 (Debian ``linuxcnc-uspace``), headless, and
read back its commanded motion at every servo period.

Why here (``planners/linuxcnc/``) and not in ``harness/``: the ``linuxcnc`` planner needs
this machinery, and planners must not import harness. It depends on nothing but the standard
library and numpy; the LinuxCNC side (``display.py``) runs under the system python3.

How: a throw-away configuration directory (INI + HAL) is generated from the machine file
(``lineardeltakins`` with its L and R, joint and axis limits, the servo period), plus a
``sampler`` on the servo thread recording joint and axis commands, ``motion.current-vel``,
``motion.program-line`` and ``motion.motion-type``. ``linuxcnc INI`` starts HAL, motion
and task, then our DISPLAY program (``display.py``) which drives the machine and drains the
sampler. ``rtapi_app`` refuses to run as root, so as root LinuxCNC runs under the
unprivileged user ``lcnc`` (``make linuxcnc`` creates it). LinuxCNC allows one instance
per host, so runs are serialised with an ``flock`` on ``/tmp/pkmbench-linuxcnc.lock``.
"""
from __future__ import annotations

import fcntl
import math
import os
import pwd
import shutil
import signal
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path as FsPath

import numpy as np

SYSTEM_PYTHON = "/usr/bin/python3"
RUN_USER = "lcnc"
LOCK_FILE = "/tmp/pkmbench-linuxcnc.lock"
INSTALL_HINT = "run `make linuxcnc` (installs Debian's linuxcnc-uspace and the user lcnc)"
# sampler columns: joints 0-2, axis x y z commands, current-vel, program-line, motion-type
SAMPLER_CFG = "fffffffss"
SAMPLER_DEPTH = 20000          # 20 s of 1 ms samples: the display drains every few ms
STARTUP_S = 60.0               # HAL + task start-up, homing and the MDI positioning move


class LinuxCNCError(RuntimeError):
    """LinuxCNC is missing or a run failed; the message is one line and names the fix."""


def missing() -> str | None:
    """Why LinuxCNC cannot run here (one line), or None when it can."""
    for exe in ("linuxcnc", "halcmd", "rtapi_app"):
        if shutil.which(exe) is None:
            return f"LinuxCNC is not installed (no `{exe}` on PATH); {INSTALL_HINT}"
    if not os.access(SYSTEM_PYTHON, os.X_OK):
        return f"{SYSTEM_PYTHON} is missing (LinuxCNC's python modules live there); {INSTALL_HINT}"
    r = subprocess.run([SYSTEM_PYTHON, "-c", "import linuxcnc, hal"], capture_output=True, text=True)
    if r.returncode != 0:
        return f"{SYSTEM_PYTHON} cannot import LinuxCNC's modules linuxcnc, hal; {INSTALL_HINT}"
    if os.geteuid() == 0:
        try:
            pwd.getpwnam(RUN_USER)
        except KeyError:
            return (f"running as root, LinuxCNC needs the unprivileged user {RUN_USER!r} "
                    f"(rtapi_app refuses root); {INSTALL_HINT}")
    return None


@dataclass
class Samples:
    """The commanded motion at every servo period from the AUTO run to the end (rows)."""
    T: float
    joints: np.ndarray        # (n, 3) joint.N.pos-cmd (joint position, not motor), mm
    xyz: np.ndarray           # (n, 3) axis.L.pos-cmd, mm
    vel: np.ndarray           # motion.current-vel, mm/s
    line: np.ndarray          # motion.program-line
    motion_type: np.ndarray   # motion.motion-type (1 traverse, 2 feed, 3 arc)
    paused_s: float = 0.0     # M0/M1 pauses left out (the operator's time): their rows are not here
    pause_uncertainty_s: float = 0.0   # ± where the pauses began, summed: half the polls' gaps

    def moving_span(self, tol: float = 1e-9) -> tuple[int, int]:
        """(k0, k1): rows k0 (at rest, last before any motion) .. k1 (first at the final
        point, after which nothing moves). The run's execution time is (k1 − k0)·T."""
        d = np.abs(np.diff(self.xyz, axis=0)).max(axis=1) > tol
        if not d.any():
            raise LinuxCNCError("LinuxCNC: the program produced no motion")
        idx = np.nonzero(d)[0]
        return int(idx[0]), int(idx[-1]) + 1


def _fmt(x: float) -> str:
    return repr(float(x))


def write_config(d: FsPath, machine, program: FsPath, start, timeout_s: float, setup=None,
                 start_delay_s: float = 0.0) -> FsPath:
    """Generate the INI and HAL files of a sim run of ``machine`` in ``d``; the INI's path.
    ``setup``: the program's tool table and parameters (planners.paths.gcode.rs274.setup.Setup,
    mm as the INI's LINEAR_UNITS) written as LinuxCNC's tool.tbl and var file."""
    if machine.family != "lineardelta":
        raise LinuxCNCError(f"linuxcnc: machine {machine.name} has {machine.family} kinematics; "
                            "the LinuxCNC runner supports lineardeltakins machines only")
    (d / "pkmbench.ini").write_text(_ini_text(d, machine, program, start, timeout_s, start_delay_s))
    (d / "pkmbench.hal").write_text(_hal_text(machine))
    (d / "tool.tbl").write_text(setup.tool_table_text() if setup and setup.tools else "T1 P1 D0 Z0 ;\n")
    (d / "sim.var").write_text(setup.var_text() if setup else "")
    shutil.copy(FsPath(__file__).with_name("display.py"), d / "display.py")
    os.chmod(d / "display.py", 0o755)
    return d / "pkmbench.ini"


def _limit_sections(machine) -> tuple[list[str], list[str]]:
    """The INI's [JOINT_n] sections (homing at the home pose, joint limits) and [AXIS_x]
    sections (Cartesian limits, the workspace box)."""
    lim = machine.limits
    q_home = machine.ik(np.asarray(machine.home, float)).ravel()
    joints = []
    for j in range(3):
        # HOME_SEARCH_VEL = 0: homing takes the current position as HOME_OFFSET and moves to
        # HOME; both at the machine's home pose, so homing does not move
        joints.append(f"""[JOINT_{j}]
TYPE = LINEAR
HOME = {_fmt(q_home[j])}
HOME_OFFSET = {_fmt(q_home[j])}
HOME_SEARCH_VEL = 0.0
HOME_LATCH_VEL = 0.0
HOME_SEQUENCE = 0
MAX_VELOCITY = {_fmt(lim.joint.v)}
MAX_ACCELERATION = {_fmt(lim.joint.a)}
MIN_LIMIT = {_fmt(machine.q_min)}
MAX_LIMIT = {_fmt(machine.q_max)}
""")
    axes = []
    for k, a in enumerate("XYZ"):
        axes.append(f"""[AXIS_{a}]
MAX_VELOCITY = {_fmt(lim.cartesian.v)}
MAX_ACCELERATION = {_fmt(lim.cartesian.a)}
MIN_LIMIT = {_fmt(machine.workspace_min[k])}
MAX_LIMIT = {_fmt(machine.workspace_max[k])}
""")
    return joints, axes


# the task and io cycles of the generated configuration; trapezoid's model of LinuxCNC's waits at
# queue syncs reads them here (planners.trapezoid.program.move_waits)
TASK_CYCLE_S = 0.001
IO_CYCLE_S = 0.100


def _ini_text(d: FsPath, machine, program: FsPath, start, timeout_s: float, start_delay_s: float = 0.0) -> str:
    """The INI: LinuxCNC's sections with lineardeltakins and the servo period, and the
    [PKMBENCH] section display.py reads (program, start point, sampler, time-out)."""
    T_ns = int(round(machine.servo_period_s * 1e9))
    lim = machine.limits
    start_words = " ".join(f"{a}{_fmt(v)}" for a, v in zip("XYZ", start))
    joints, axes = _limit_sections(machine)
    return f"""# generated by pkmbench (planners/linuxcnc/runner.py) for machine {machine.name}
[EMC]
VERSION = 1.1
MACHINE = pkmbench-{machine.name}
DEBUG = 0

[DISPLAY]
DISPLAY = {d / 'display.py'}

[TASK]
TASK = milltask
CYCLE_TIME = {_fmt(TASK_CYCLE_S)}

[RS274NGC]
PARAMETER_FILE = sim.var

[EMCMOT]
EMCMOT = motmod
COMM_TIMEOUT = 1.0
SERVO_PERIOD = {T_ns}

[HAL]
HALFILE = pkmbench.hal

[TRAJ]
COORDINATES = X Y Z
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
DEFAULT_LINEAR_VELOCITY = {_fmt(lim.feed_max)}
MAX_LINEAR_VELOCITY = {_fmt(lim.feed_max)}
POSITION_FILE = position.txt

[KINS]
KINEMATICS = lineardeltakins
JOINTS = 3

{chr(10).join(joints)}
{chr(10).join(axes)}
[EMCIO]
EMCIO = io
CYCLE_TIME = {_fmt(IO_CYCLE_S)}
TOOL_TABLE = tool.tbl

[PKMBENCH]
OUTPUT = {d / 'samples.txt'}
PROGRAM = {program}
START = {start_words}
SAMPLER_CFG = {SAMPLER_CFG}
TIMEOUT_S = {_fmt(timeout_s)}
START_DELAY_S = {_fmt(start_delay_s)}
"""


def _hal_text(machine) -> str:
    """The HAL file: kinematics with the machine's L and R, motion, joints looped back
    (a sim), the sampler on the servo thread and the I/O loops task needs."""
    return f"""# generated by pkmbench: lineardeltakins sim with a sampler on the servo thread
loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
loadrt sampler depth={SAMPLER_DEPTH} cfg={SAMPLER_CFG}
addf motion-command-handler servo-thread
addf motion-controller servo-thread
addf sampler.0 servo-thread
setp lineardeltakins.L {_fmt(machine.params['L'])}
setp lineardeltakins.R {_fmt(machine.params['R'])}
net j0 joint.0.motor-pos-cmd => joint.0.motor-pos-fb
net q0 joint.0.pos-cmd => sampler.0.pin.0
net j1 joint.1.motor-pos-cmd => joint.1.motor-pos-fb
net q1 joint.1.pos-cmd => sampler.0.pin.1
net j2 joint.2.motor-pos-cmd => joint.2.motor-pos-fb
net q2 joint.2.pos-cmd => sampler.0.pin.2
net px axis.x.pos-cmd => sampler.0.pin.3
net py axis.y.pos-cmd => sampler.0.pin.4
net pz axis.z.pos-cmd => sampler.0.pin.5
net vel motion.current-vel => sampler.0.pin.6
net line motion.program-line => sampler.0.pin.7
net mtype motion.motion-type => sampler.0.pin.8
net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed
"""


def _kill(proc: subprocess.Popen) -> None:
    """End the LinuxCNC process group we started: SIGTERM (the linuxcnc script cleans up
    HAL and rtapi_app on it), SIGKILL if it does not go."""
    for sig, wait in ((signal.SIGTERM, 20), (signal.SIGKILL, 5)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(wait)
            return
        except subprocess.TimeoutExpired:
            continue


def run_program(program_text: str, machine, start, expected_s: float | None = None,
                keep_dir: str | None = None, setup=None, start_delay_s: float = 0.0) -> Samples:
    """Run G-code ``program_text`` on LinuxCNC for ``machine``; the tool is first moved to
    ``start`` (xyz, mm) by MDI, then the program runs in AUTO while the sampler records.

    ``expected_s`` (a rough duration) sizes the time-out; ``keep_dir`` keeps the generated
    configuration and LinuxCNC's logs there (for debugging); ``setup``: the tool table and
    var file LinuxCNC starts with (see write_config); ``start_delay_s``: wait that long before
    AUTO run (the io task's free-running cycle then meets the program at another phase).
    The rows of an M0/M1 pause (display.py: from when it began to the resume) are left out.
    """
    why = missing()
    if why:
        raise LinuxCNCError(why)
    timeout = 3.0 * (expected_s or 60.0) + 60.0
    root = os.geteuid() == 0
    d = FsPath(tempfile.mkdtemp(prefix="pkmbench-lcnc-"))
    ok = False
    try:
        (d / "program.ngc").write_text(program_text)
        ini = write_config(d, machine, d / "program.ngc", start, timeout, setup, start_delay_s)
        env = {"PATH": "/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin", "HOME": str(d),
               "LANG": "C", "LC_ALL": "C"}
        cmd = ["linuxcnc", str(ini)]
        if root:
            pw = pwd.getpwnam(RUN_USER)
            for p in [d, *d.iterdir()]:
                os.chown(p, pw.pw_uid, pw.pw_gid)
            env["USER"] = env["LOGNAME"] = RUN_USER
            cmd = ["runuser", "-u", RUN_USER, "--"] + cmd
        with open(LOCK_FILE, "a+") as lock:
            if root:
                os.chmod(LOCK_FILE, 0o666)
            fcntl.flock(lock, fcntl.LOCK_EX)      # one LinuxCNC per host: wait our turn
            with open(d / "linuxcnc.log", "w") as log:
                proc = subprocess.Popen(cmd, cwd=d, env=env, stdout=log, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, start_new_session=True)
                try:
                    proc.wait(timeout + STARTUP_S)
                except subprocess.TimeoutExpired:
                    _kill(proc)
                    raise LinuxCNCError(f"linuxcnc: no end after {timeout + STARTUP_S:.0f} s "
                                        f"(log kept in {_keep(d, keep_dir, force=True)})") from None
                except BaseException:
                    _kill(proc)
                    raise
        err = d / "samples.txt.err"
        if err.exists():
            raise LinuxCNCError(err.read_text().strip().splitlines()[0]
                                + f" (log in {_keep(d, keep_dir, force=True)})")
        if not (d / "samples.txt").exists():
            tail = (d / "linuxcnc.log").read_text(errors="replace").strip().splitlines()[-3:]
            raise LinuxCNCError(f"linuxcnc exited with status {proc.returncode} and no samples: "
                                f"{' | '.join(tail)} (log in {_keep(d, keep_dir, force=True)})")
        samples = _read_samples(d / "samples.txt", machine.servo_period_s, d / "samples.txt.pauses")
        ok = True
        return samples
    finally:
        if ok:
            _keep(d, keep_dir)


def _keep(d: FsPath, keep_dir: str | None, force: bool = False) -> str:
    """Move the run directory to ``keep_dir`` (or leave it in /tmp when ``force``)."""
    if keep_dir:
        dst = FsPath(keep_dir)
        if dst.exists():
            shutil.rmtree(dst)
        shutil.move(str(d), dst)
        return str(dst)
    if force:
        return str(d)
    shutil.rmtree(d, ignore_errors=True)
    return ""


def _read_samples(file: FsPath, T: float, pauses: FsPath | None = None) -> Samples:
    data = np.loadtxt(file, ndmin=2)
    if len(data) < 2:
        raise LinuxCNCError(f"linuxcnc: only {len(data)} sample(s) recorded")
    n = data[:, 0]
    gaps = np.nonzero(np.diff(n) != 1)[0]
    if len(gaps):
        raise LinuxCNCError(f"linuxcnc: sampler rows not consecutive after sample {int(n[gaps[0]])}")
    # an M0/M1 pause lasts as long as the operator: its rows (at rest) are left out
    drop = np.zeros(len(data), bool)
    gaps_sum = 0
    if pauses is not None and pauses.is_file():
        for a, b, gap in (map(int, ln.split()) for ln in pauses.read_text().splitlines() if ln.strip()):
            gaps_sum += gap
            rows = (n >= a) & (n <= b)
            if rows.any() and np.abs(data[rows, 4:7] - data[rows, 4:7][0]).max() > 0.0:
                raise LinuxCNCError(f"linuxcnc: the tool moved during the pause at samples {a}..{b}")
            drop |= rows
    data = data[~drop]
    return Samples(T, data[:, 1:4], data[:, 4:7], data[:, 7], data[:, 8].astype(int),
                   data[:, 9].astype(int), float(drop.sum()) * T, 0.5 * gaps_sum * T)


def finite_or(x, default):
    return x if x is not None and math.isfinite(x) else default
