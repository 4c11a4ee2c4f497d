"""The HTML report (issue 22): the performance profile against hand-computed values, feed over
arc length against a constant-speed line, and the report opened in a real headless Chromium:
plotly drew every plot (the DOM after the scripts ran) and the screenshot shows the table (its
header colour) and the plots (plotly's first trace colour, the red regression marker)."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main as cli
from harness.report.html_report import TABLE_HEAD_COLOUR, along_path
from harness.store import ResultStore, make_row

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}


def row(case, planner, t, feasible=True, seed=0):
    return {"machine": "m", "path": case, "preset": "none", "variation": "base", "seed": seed, "planner": planner,
            "status": "ok" if t else "error",
            "metrics": {"execution_time_s": t, "feasible": feasible} if t else None}


def test_performance_profile_by_hand():
    """The report's profile is harness.perfprofile's (the corpus's): joint-feasible runs only,
    a case = machine × path × preset × variation, its seeds runs of it."""
    from harness import perfprofile
    from harness.report.html_report import _profile_runs
    rows = [row("A", "p1", 1.0), row("A", "p2", 2.0), row("B", "p1", 3.0), row("B", "p2", 1.5), row("B", "p3", None),
            row("B", "p4", 0.5, feasible=False), row("A", "p5", 1.0, seed=0), row("A", "p5", 4.0, seed=1)]
    runs = _profile_runs(rows)
    assert sorted({c for c, _, _ in runs}) == ["m/A/none/base", "m/B/none/base"]
    tau = [1.0, 2.0, 4.0]
    prof = perfprofile.performance_profile(runs, tau)
    # A: p1 1, p2 2, p5 1 and 4 (half each); B: p1 3/1.5 = 2, p2 1; p3 failed; p4 broke the joint
    # limits: its 0.5 s neither counts nor sets B's best
    assert prof["p1"].tolist() == [0.5, 1.0, 1.0] and prof["p2"].tolist() == [0.5, 1.0, 1.0]
    assert prof["p3"].tolist() == [0.0, 0.0, 0.0] and prof["p4"].tolist() == [0.0, 0.0, 0.0]
    assert prof["p5"].tolist() == [0.25, 0.25, 0.5]
    # the spread band: p5's best seed alone (1.0) and its worst (4.0)
    best = perfprofile.performance_profile(_profile_runs(rows, worst=False), tau)
    worst = perfprofile.performance_profile(_profile_runs(rows, worst=True), tau)
    assert best["p5"].tolist() == [0.5, 0.5, 0.5] and worst["p5"].tolist() == [0.0, 0.0, 0.5]


def test_along_path_feed_of_a_constant_speed_line(tmp_path):
    from kins import load_machine
    m = load_machine("keops")
    T, v = m.servo_period_s, 120.0
    t = np.arange(200) * T
    P = np.column_stack([-50 + v * t, np.zeros_like(t), np.full_like(t, -400.0)])
    from harness.cosim.record import write_command_csv
    write_command_csv(tmp_path / "command.csv", t, P, m.ik(P))
    c = along_path(tmp_path, m)
    assert c["s"][-1] == pytest.approx(v * t[-1], rel=1e-12)
    assert np.allclose(c["feed"][1:], v, rtol=1e-9)
    # the joint velocity ratio of IK at constant Cartesian speed: by the kinematics' own Jacobian
    q = m.ik(P)
    assert c["worst"][5] >= np.abs(np.diff(q, axis=0))[4].max() / T / m.limits.joint.v - 1e-12


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("report")
    (tmp / "line.json").write_text(json.dumps(LINE))
    suite = tmp / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{tmp / "line.json"}"\nplanners = ["trapezoid", "scurve"]\n')
    assert cli(["sweep", str(suite), "--workers", "0", "--no-progress", "--task", "harness.sweep.tasks:plan_task",
                "--out", str(tmp / "sw"), "--store", str(tmp / "store")]) == 0
    # four nightly runs; the third has execution_time_s out of tolerance
    t0 = datetime(2026, 1, 1, tzinfo=timezone.utc)
    with ResultStore(tmp / "store") as st:
        for i, t in enumerate((1.0, 1.01, 1.3, 1.0)):
            st.append([make_row(entry="keops/line/scurve/seed0/none/base", machine="keops", path="line",
                                planner="scurve", seed=0, metrics={"execution_time_s": t},
                                regressions=["execution_time_s"] if i == 2 else [])],
                      kind="ci", run_info={"passed": i != 2}, time=t0 + timedelta(days=i))
    assert cli(["report", str(tmp / "sw"), "--store", str(tmp / "store")]) == 0
    return tmp / "sw/report/report.html"


def test_report_is_self_contained_and_deterministic(report, tmp_path):
    from html.parser import HTMLParser
    text = report.read_text()
    external = []

    class Tags(HTMLParser):           # script bodies are not parsed: plotly.js's own strings do not count
        def handle_starttag(self, tag, attrs):
            a = dict(attrs)
            if (tag in ("script", "img", "iframe") and a.get("src")) or (tag == "link" and a.get("href")):
                external.append((tag, a))
    Tags().feed(text)
    assert external == []                                  # no server, no CDN: plotly.js inlined
    assert text.count("Plotly.newPlot") == 3            # the profile, along the path, the trend of the one metric
    assert "<table class='comparison'>" in text and "trapezoid" in text and "scurve" in text
    assert "red" in text and "regression" in text
    first = report.read_bytes()
    assert cli(["report", str(report.parent.parent), "--store", str(report.parent.parent.parent / "store")]) == 0
    assert report.read_bytes() == first


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine: `make browser` installs Debian's")
def test_report_renders_in_headless_chromium(report, tmp_path):
    from PIL import Image
    args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            "--virtual-time-budget=15000", "--window-size=1280,3600"]
    dom = subprocess.run(args + ["--dump-dom", report.as_uri()], capture_output=True, text=True, timeout=180)
    assert dom.returncode == 0, dom.stderr[-2000:]
    # plotly replaced each plot's div by its SVG: the scripts ran in the browser
    assert dom.stdout.count('class="main-svg"') >= 2 * 3, dom.stdout[:500]
    shot = tmp_path / "report.png"
    r = subprocess.run(args + [f"--screenshot={shot}", report.as_uri()], capture_output=True, text=True, timeout=180)
    assert r.returncode == 0 and shot.exists(), r.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB")).astype(int)

    def pixels(hex_colour: str, tol: int = 6) -> int:
        c = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])
        return int((np.abs(img - c).max(axis=2) <= tol).sum())

    # the table header (13 columns × ~25 px tall) and plotly's first trace colour (#636efa)
    assert pixels(TABLE_HEAD_COLOUR) > 5000
    assert pixels("#636efa") > 200
    assert pixels("#ff0000", tol=20) > 50                # the regression ✕
