"""The standard paths fit their machines (kins.check finds nothing along the dense path)."""
import numpy as np
import pytest

from kins import load_machine
from planners.paths import resolve_path

FITS = [("bird", "keops"), ("bird_flat", "keops"), ("flower", "keops"), ("helix", "keops"),
        ("bird_kossel", "kossel"), ("test_part.ngc", "kossel")]


@pytest.mark.parametrize("name, machine", FITS)
def test_standard_path_fits_machine(name, machine):
    m = load_machine(machine)
    p = resolve_path(name)
    s, P = p.sample(0.05)
    findings = m.check(P)
    assert findings == [], findings[:3]
    lo, hi = p.bounds()
    assert (lo >= m.workspace_min).all() and (hi <= m.workspace_max).all()


def test_bird_shape():
    p = resolve_path("bird")
    lo, hi = p.bounds()
    assert np.allclose(hi[:2] - lo[:2], 160.0, atol=4.0)           # 160 × 160 mm area
    assert np.allclose(0.5 * (hi[:2] + lo[:2]), [0, 0], atol=10.0)  # around the keops centre …
    # … on the plane z = −400 − 0.5·(x + y) through it (the flat twin lies at z = −400)
    s = np.linspace(0, p.length, 2001)
    P, F = p.point(s), resolve_path("bird_flat").point(s * resolve_path("bird_flat").length / p.length)
    assert np.allclose(P[:, 2], -400 - 0.5 * (P[:, 0] + P[:, 1]), atol=1e-9)
    assert np.allclose(F[:, 2], -400, atol=1e-12)
    assert len(p.corners()) >= 4                                    # sharp corners
    s = np.linspace(0, p.length, 20001)
    k = p.curvature(s)
    # several feed minima: local curvature maxima with radius < 20 mm away from the corners
    peaks = np.where((k[1:-1] > k[:-2]) & (k[1:-1] >= k[2:]) & (k[1:-1] > 1 / 20))[0]
    assert len(peaks) >= 3
    assert 0.5 < p.length / 1000.0 < 3.0                            # 1000 mm/s → 0.5–3 s


def test_flower_closed_and_kossel_bird_scaled():
    f = resolve_path("flower")
    assert np.allclose(f.point(0.0), f.point(f.length), atol=1e-12)
    b, bk = resolve_path("bird_flat"), resolve_path("bird_kossel")
    assert bk.length == pytest.approx(0.5 * b.length, rel=1e-9)
