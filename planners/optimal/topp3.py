"""TOPP3-SOCP on a station grid (COPP's transcription, solved by ipm.py's banded interior-point
method or copp-py's Clarabel: Settings.solver), checked and repaired
at T: the engine of the planners `copp` and `optimal` (which adds scurve_joint's profile where
faster, the NLP's polish on short pieces and the bound of the station relaxation).

Wang, Hu, Li, Yu, Yan, Liang & Jin, "Online time-optimal trajectory planning along parametric
toolpaths with strict constraint satisfaction and certifiable feasibility guarantee", Int. J.
Machine Tools and Manufacture 215 (2026) 104355; the `copp-py` package (Rust core, Clarabel).
The constraint set is the planners' one: joint velocity, acceleration and jerk limits, the
feed caps (F_max, the programmed feed, the chord-error cap F_clim of TII 2022) and at a G1
join the jerk its jump of q″ reads as at T.

Per rest-to-rest piece (split at exact-stop corners) COPP works on a station grid over arc
length with a = ṡ² and b = s̈ at the stations, b linear in s between them (so s⃛ = ṡ·c with
c = db/ds constant on an interval).  Velocity and acceleration limits are linear in (a, b); the
jerk limit √a·(q‴a + 3q″b + q′c) ≤ J is linearised around a reference profile a_lin by a
tangent of J/√a, which lies below it: a solution of the linearised problem keeps the jerk
limit at the stations, and stays feasible when the next problem is linearised around it, so
the time never grows from one linearisation to the next (sequential convex programming).  The
first reference is TOPP2-RA's jerk-free profile; the linearisations go on until a solve gains
< lin_tol of the time (or, with Settings.lin_predicted, until the tangents' shortfall at the
solution predicts the next would gain less: linearisation_cost).  The feed caps are bounds
a ≤ cap² at the stations.  At a G1 join (a station) |jerk + κṡ²| ≤ J with
κ = JUMP_READ_FACTOR·Δq″/T, Δq″ signed from the left side to the right (a third difference at T
reads the jump with its sign), for the one-sided derivatives either side: κa = √a·κ√a; on the
side where the read adds to the jerk, κ√a is replaced by its tangent at a_lin (√a is concave,
so the tangent row is the stricter), on the other the row is |jerk| ≤ J (the read dropped: a
restriction too).  `optimal` (Settings.window_reads) holds the jump as every third difference at
T whose window holds it reads it instead: the kernel's average of q̈ = q′s̈ + q″ṡ², linear in
(a, b) on the linearisation's time map, at 23 phases about each join (Piece._window_reads); the
pointwise rows held the jerk off J at every station near a join where only a window's average
has to be (what that cost: docs/TUNING.md).

Time is scaled by t_u = A/J of the joints (limits V·t_u, A·t_u², J·t_u³): in mm and s the
magnitudes of a, b and the jerk lie far apart and Clarabel returned a profile far from the
optimum (docs/TUNING.md).

Stations: ≤ grid_mm apart, every segment end and G1 join on the grid, refined at curvature
peaks (for `optimal` also graded 2× outward from every join, whose read the graded stations
within 1.5 periods' travel hold too, weighted: Settings.join_grading, and split where a coarser
solution's speed changes fast and toward the rest ends: speed_stations); q′, q″, q‴ at each
station from the IK's stencil (constraints.joint_derivs), not interpolated.  The limits hold
at the stations.  Between them (a(s) is quadratic there and bulges over a bound held at both
ends) the check at T can read above them: the profile is sampled at T and checked; where a
difference window reads a limit r > 1, that limit is held to its fraction / (r·(1 + extra)) at
the stations under the window and one either side (extra doubling with each time that station
was tightened before), and only a window of stations around
those is solved again, its ends held at the last solution's a and b (a window's solve is a
fraction of a whole piece's), up to MAX_REPAIRS rounds; where a limit still reads above then,
the last resort returns the fastest, of those within the limits, of every round's profile
stretched in time around its reads by whole periods (timewarp.Local) and of the last round's
pieces stretched uniformly (timewarp.Uniform).
A profile still above a limit after that is returned as it is (info["above_at_T"] counts
its windows): the harness's check reports it.
"""
from __future__ import annotations

import dataclasses
import math

import copp_py as copp
import numpy as np

from planners.constraints import (JUMP_READ_FACTOR, READ_REACH, PathTable, PlanningError, cartesian_derivs,
                                  check_limits, check_path, cross_norm, curvature_splits, feed_cap,
                                  interior_knots, join_jumps, join_read_weight, joint_derivs, rest_pieces,
                                  second_derivative_kernel, station_grid)
from planners.optimal import ipm, timewarp
from planners.optimal.ipm import LIN_FLOOR
from planners.profile import Profile, Rest
from planners.verify import FEASIBLE_TOL, stretch_need, windows_above

# stations ≤ STATION_RADII curvature radii apart (the jerk between stations at lobe tips and
# blend arcs read above the limit where they were sparser), by default no closer than
# STATION_MIN_MM (closer, Clarabel stopped on insufficient progress before it was accepted and
# its last iterate checked at T; `optimal` resolves µm tips below it: Settings.station_min_mm)
STATION_RADII = 0.5
STATION_MIN_MM = 1e-3
# knot stations (Settings.knot_stations) this far either side of the knot: one-sided derivatives
KNOT_SIDE_MM = 1e-7
# Settings.knot_cells: at every interior NURBS knot a station, and one this far either side.
# The engine holds the jerk limit at both ends of every cell with the stations' derivatives, so a
# cell across a knot, where q‴ jumps, held one c = ds̈/ds to both sides' q‴: a false cap
# ṡ³ ≲ 2J/|Δq‴| (rand_3d_lcnc passed its knot at s = 567.39 mm at 143 mm/s, the reference at 157).
# With the knot's own jerk rows left out, the cell either side holds the jerk with its side's q‴
# only, and s⃛ jumps at the knot as the continuous optimum's does
KNOT_CELL_MM = 1e-4
# ... the knot station's jerk limit: this many times J (no row binds it)
KNOT_JERK_FREE = 1e6
# ... at the knots where a coarser solution passes at this share of the false cap or more: cells
# at every knot cost keops's random NURBS paths 0.05–0.1 %, at 0.8 of it rand_3d_weights_keops
# 0.03 %, at 0.9 nothing (docs/TUNING.md)
KNOT_CAP_SHARE = 0.9
# speed_stations: cells across which a coarser solution's speed ṡ changes by more than SPEED_STEP
# of its lower end are split so that it changes by about that much on each.  b = s̈ is linear in s
# on a cell, so s⃛ = ṡ·db/ds follows ṡ across it, and the jerk limit, held at both ends, binds at
# the faster one only: from rest, where ṡ ∝ s^⅔ in the jerk-limited start, the cells of a uniform
# grid held the jerk 0.6–0.9 J at their slow ends and a 5 mm move of contour_lcnc stayed 0.75 %
# above its closed-form time at any spacing (0.1 % with this split at 0.01, 0.2 % at 0.02:
# docs/TUNING.md)
SPEED_STEP = 0.01
# ... and the cell at a rest end graded geometrically (ratio 1 + 1.5·SPEED_STEP: ṡ ∝ s^⅔) down to
# the travel of a jerk-limited start in REST_FIRST_TU time units t_u = A/J: COPP's cell from rest
# has one constant path jerk, which the jerk at its far end (3q″ṡs̈ adds to q′s⃛) bounds
REST_FIRST_TU = 0.05
# ... a cell split into at most this many (a stop inside a piece has ṡ → 0 at one end)
SPEED_SPLIT_MAX = 64
# Settings.join_grading: either side of a G1 join, stations 2^k × the travel in one period at
# the join's cap (a blend arc's cell where smaller), k ≥ 0, up to the next station; none
# closer than GRADED_MIN_MM.  At a corner of a G64 program the feed falls to ~0.05 mm/s over
# µm: on the line's 0.05 mm cell beside it, a(s) left it as one quadratic, whose time (a log
# near a ≈ 0) the SOCP's chord time misses; a 2× grading bounds a's ratio across each cell.
GRADED_MIN_MM = 1e-6
# rounds of the check at T and local tightening; a limit is tightened at a station by
# TIGHTEN_EXTRA more than it read, doubled each time that station's limit was tightened before
# (windows next to a G1 join read above again by less each time).  Doubled each round instead,
# a window first read in a late round was tightened far more than it read, and on a program of
# many G1 joins the rounds compounded instead of converging (docs/TUNING.md); then the last
# resort's time stretches (_stretch), each up to MAX_STRETCHES rounds (a uniform stretch moves
# every later piece's samples at T, so a piece not stretched yet can read above next: long
# programs of many pieces need many)
MAX_REPAIRS = 20
TIGHTEN_EXTRA = 1e-3
MAX_STRETCHES = 24
# Settings.window_reads: the centres of the third differences held about each G1 join, in periods
# from it (a window centred further than 1.5 periods off does not hold the jump), by ⅛ period: the
# corpus reference's phases (benchmarks/paths/corpus/reference.py KERNEL_PHASES: by ¼ its profiles
# read up to 1.013 × J between two centres)
READ_CENTRES = np.arange(-11, 12) / 8
# a local stretch (timewarp.py) with more bumps than this gives way to the uniform one
# (reads above all along a piece: a bump per τ of it)
MAX_BUMPS = 4000
# a stretch is by the worst need and this much more: it moves every sample at T, so it cannot
# aim at 1 exactly, but TIGHTEN_EXTRA's 1e-3 cost 0.1 % of the piece's time for reads of 1 + 1e-6
STRETCH_EXTRA = 1e-5
LIMIT_COLUMNS = ("velocity", "acceleration", "jerk", "feed")
# a stop inside a piece: a ≤ STOP_A of the piece's largest a (_stops_at_rest)
STOP_A = 1e-6
# a repair re-solves the stations whose limits were tightened and, either side, the travel of
# WINDOW_TU time units t_u = A/J (a jerk-limited change of speed takes ~2 t_u) at the fastest
# of them, at least WINDOW_STATIONS stations, its ends held at the last solution; where that
# window has no solution (too short to slow down in) it is widened WINDOW_GROWTH times,
# up to the whole piece
WINDOW_TU = 3.0
WINDOW_STATIONS = 40
WINDOW_GROWTH = 2


@dataclasses.dataclass(frozen=True)
class Settings:
    """How the engine runs: ``name`` (the planner, in messages and on the Profile), stations
    ≤ ``grid_mm`` apart, linearisations until a solve gains < ``lin_tol`` of the piece's time,
    at most ``max_linearisations`` solves (COPP's; docs/TUNING.md says what more cost and
    gained).  ``kkt_refinement``: Clarabel refines each solve of its KKT system iteratively
    (copp-py's default, kept for every planner on the engine): without, the profiles move
    under other numpy SIMD paths more than the reproducibility contract allows (docs/TUNING.md).
    ``station_radii``: stations ≤ this many curvature radii apart (STATION_RADII by default),
    none closer than ``station_min_mm`` (STATION_MIN_MM by default).
    ``knot_stations``: a station a hair either side of every interior NURBS knot (grid_of).
    ``knot_cells``: arc lengths of NURBS knots (binding_knots) to hold as a station without jerk
    rows and one KNOT_CELL_MM either side (KNOT_CELL_MM).
    ``join_grading``: stations graded 2× outward from every G1 join (_graded, GRADED_MIN_MM).
    ``window_reads``: a G1 join's jump held as every third difference at T reads it, whatever
    the samples' phase (Piece._window_reads), in place of the rows at the join's graded stations.
    ``extra_stations``: arc lengths to hold as stations too (speed_stations).
    ``read_slack``: the samples at T are repaired only where they read a joint limit above
    1 + read_slack (a planner that hands the engine its joint limits less a margin lets its
    samples use part of it, rather than chase reads of a few 10⁻⁶ from window to window; F_max
    has no margin and keeps no slack).
    ``midpoint_cap``: the feed cap also at the middle of every cell (Piece._rows).
    ``read_phases``: the repairs read the samples at T with the motion's start delayed by
    k·T/read_phases, k = 0 … read_phases − 1, not only at k = 0: a join's jump of q″ reads
    differently at each phase, and a profile repaired at one phase read up to 1.09 × J at
    another (docs/TUNING.md, "the phase of the samples"). The last resort (stretches) reads k = 0.
    ``lin_predicted``: the linearisations also stop where the next one is predicted to gain less
    than this fraction of the time (linearisation_cost), without the solve that would confirm
    it; None: only a solve's own gain stops them (COPP's rule).
    ``solver``: "ipm" (ipm.py: the banded interior-point method; where it stops without a
    solution, Clarabel on the same rows) or "clarabel" (copp-py's own solve, COPP as published)."""
    name: str
    grid_mm: float = 0.1
    lin_tol: float = 1e-3
    max_linearisations: int = 4
    kkt_refinement: bool = True
    station_radii: float = STATION_RADII
    station_min_mm: float = STATION_MIN_MM
    knot_stations: bool = False
    knot_cells: tuple = ()
    join_grading: bool = False
    window_reads: bool = False
    extra_stations: tuple = ()
    read_slack: float = 0.0
    midpoint_cap: bool = False
    read_phases: int = 1
    lin_predicted: float | None = None
    solver: str = "ipm"

    def clarabel(self):
        """Clarabel's options: one solve accepts insufficient progress (Piece._socp)."""
        opts = copp.clarabel.ClarabelOptions(allow_insufficient_progress=True)
        raw = opts.clarabel_settings
        raw.iterative_refinement_enable = self.kkt_refinement
        opts.clarabel_settings = raw
        return opts


def grid_of(path, table, joins, s0, s1, grid_mm, radii=STATION_RADII, knots=False, min_mm=STATION_MIN_MM):
    """planners.constraints.station_grid with every segment end and G1 join of the piece on it,
    then cells split to ≤ ``radii`` curvature radii (at their ends), none below ``min_mm``.
    ``knots``: also a station KNOT_SIDE_MM either side of every interior NURBS knot, where P‴
    jumps: a rational NURBS's q‴ can peak right after a knot and fall back between two stations
    (docs/TUNING.md)."""
    inner = [sj for sj, _ in joins if s0 + 1e-6 < sj < s1 - 1e-6]
    edges = np.unique(np.concatenate([table.edges[(table.edges > s0) & (table.edges < s1)],
                                      inner, [s0, s1]]))
    grid = station_grid(edges, grid_mm, s0, s1)
    sk = interior_knots(path) if knots else np.zeros(0)
    if len(sk):
        sk = np.concatenate([sk - KNOT_SIDE_MM, sk + KNOT_SIDE_MM])
        sk = sk[(sk > s0 + 1e-6) & (sk < s1 - 1e-6)]
        grid = np.unique(np.concatenate([grid, sk]))
    for _ in range(6):
        _, P1, P2, _ = cartesian_derivs(path, np.clip(grid, s0 + 1e-9, s1 - 1e-9))
        h = np.diff(grid)
        need, parts = curvature_splits(h, cross_norm(P1, P2), radii, min_mm, 16)
        if len(need) == 0:
            break
        new = np.concatenate([grid[i] + h[i] * np.arange(1, k) / k for i, k in zip(need, parts)])
        grid = np.sort(np.concatenate([grid, new]))
    return grid


def binding_knots(pieces, path, machine, limits, share=KNOT_CAP_SHARE) -> tuple:
    """The interior NURBS knots (none at a G1 join, which has its own rows) where the solved
    ``pieces`` pass at ≥ ``share`` of the false cap (2J/max|Δq‴|)^⅓ that one c across the knot's
    cell puts on the speed: Settings.knot_cells for a finer solve (KNOT_CELL_MM)."""
    sk = interior_knots(path)
    if len(sk) == 0:
        return ()
    q3 = joint_derivs(machine, path, np.concatenate([sk - 1e-7, sk + 1e-7]), fit_scale=True)[3]
    jump = np.abs(q3[len(sk):] - q3[:len(sk)]).max(axis=1)
    with np.errstate(divide="ignore"):
        cap = np.cbrt(2 * limits.joint.j / jump)
    out = []
    for p in pieces:
        inside = (sk > p.s0 + 2 * KNOT_CELL_MM) & (sk < p.s1 - 2 * KNOT_CELL_MM)
        joins = p.grid[[r[0] for r in p.joins]]
        if len(joins):
            inside &= np.abs(sk[:, None] - joins[None, :]).min(axis=1) > 2 * KNOT_CELL_MM
        if p.relaxed is None or not inside.any():
            continue
        speed = np.sqrt(np.maximum(np.interp(sk[inside], p.grid, p.relaxed.a), 0.0)) / p.tu
        out += [float(k) for k, v, c in zip(sk[inside], speed, cap[inside]) if v >= share * c]
    return tuple(out)


def speed_stations(pieces, step=SPEED_STEP, first_tu=REST_FIRST_TU) -> tuple:
    """Stations (mm) for a finer solve: the solved ``pieces``' cells across which ṡ changes by
    more than ``step`` of its slower end split evenly (≤ SPEED_SPLIT_MAX parts), and the cell at
    each rest end graded geometrically toward it (SPEED_STEP, REST_FIRST_TU)."""
    out = []
    for p in pieces:
        if p.relaxed is None:
            continue
        g = p.grid
        v = np.sqrt(np.maximum(p.relaxed.a, 0.0))
        lo, dv = np.minimum(v[:-1], v[1:]), np.abs(np.diff(v))
        inner = np.arange(1, len(g) - 2)
        split = inner[(lo[inner] > 0) & (dv[inner] > step * lo[inner])]
        for i in split:
            n = min(int(math.ceil(dv[i] / (step * lo[i]))), SPEED_SPLIT_MAX,
                    int((g[i + 1] - g[i]) / GRADED_MIN_MM))
            out.append(g[i] + (g[i + 1] - g[i]) * np.arange(1, n) / n)
        ratio = 1 + 1.5 * step
        for end, d, q1 in ((g[0], g[1] - g[0], p.deriv[1][0]), (g[-1], g[-2] - g[-1], p.deriv[1][-1])):
            # the start from rest at the path jerk J/|q′| covers J/|q′|·t³/6 (scaled time)
            first = max(p.lims[2] / max(float(np.abs(q1).max()), 1e-12) * first_tu ** 3 / 6, GRADED_MIN_MM)
            k = np.arange(1, max(int(math.log(abs(d) / first) / math.log(ratio)), 0) + 1)
            out.append(end + d * ratio ** -k)
    return tuple(np.sort(np.concatenate(out)).tolist()) if out else ()


def _with_stations(grid, extra):
    """The grid with the ``extra`` stations inside it, less those nearer a station of the grid than
    a third of their spacing to the next extra one (no sliver cells: Clarabel stopped on numerical
    errors beside them)."""
    x = extra[(extra > grid[0]) & (extra < grid[-1])]
    if len(x) == 0:
        return grid
    gap = np.minimum(np.diff(x, prepend=-np.inf), np.diff(x, append=np.inf))
    gap = np.minimum(gap, np.minimum(x - grid[0], grid[-1] - x))
    i = np.clip(np.searchsorted(grid, x), 1, len(grid) - 1)
    near = np.minimum(x - grid[i - 1], grid[i] - x)
    return np.unique(np.concatenate([grid, x[near > gap / 3]]))


def _graded(grid, at, first):
    """The grid with, either side of each station grid[i] for i in ``at``, stations h·2^k away
    (k ≥ 0, h: the smaller of its two cells and first[m], at least GRADED_MIN_MM) up to the
    next station."""
    new = []
    for i, h0 in zip(at, first):
        h = max(min(grid[i] - grid[i - 1], grid[i + 1] - grid[i], h0), GRADED_MIN_MM)
        for side, room in ((-1, grid[i] - grid[i - 1]), (1, grid[i + 1] - grid[i])):
            off = h * 2.0 ** np.arange(max(int(math.log2(room / h)), 0) + 1)
            new.append(grid[i] + side * off[off < room - h / 2])
    return np.unique(np.concatenate([grid, *new]))


def _join_rows(machine, path, grid, joins, T_scaled):
    """[(station, q′, q″, q‴ either side (2, 3), κ per joint)] of the G1 joins on the grid,
    T in scaled time: the jump Δq″ reads at T as a jerk κṡ², κ = JUMP_READ_FACTOR·Δq″/T, signed
    (q″ from the left side to the right; join_jumps gives its size)."""
    out = []
    for sj, dq2 in joins:
        i = int(np.searchsorted(grid, sj))
        if 0 < i < len(grid) - 1 and abs(grid[i] - sj) < 1e-9:
            _, D1, D2, D3 = joint_derivs(machine, path, np.array([sj - 1e-7, sj + 1e-7]), fit_scale=True)
            sign = np.sign(D2[1] - D2[0])
            out.append((i, D1, D2, D3, JUMP_READ_FACTOR * sign * np.asarray(dq2) / T_scaled))
    return out


def _one_sided(deriv, joins):
    """((q′, q″) on the right of each station, (q′, q″) on its left): the stations' own values,
    a G1 join's station its two sides' (joins: _join_rows)."""
    right = [deriv[1].copy(), deriv[2].copy()]
    left = [deriv[1].copy(), deriv[2].copy()]
    for i, D1, D2, *_ in joins:
        left[0][i], left[1][i] = D1[0], D2[0]
        right[0][i], right[1][i] = D1[1], D2[1]
    return tuple(right), tuple(left)


class Piece:
    """One rest-to-rest piece as a COPP problem in scaled time (t_u = A/J); ``reference``: the
    profile (a at the stations) the first solve is linearised around, TOPP2-RA's where None;
    ``relaxed``: the first solve's profile (the limits at the stations only, before any
    tightening); ``reference_is_coarser``: the reference is another grid's solution
    (linearise_around), so the linearisations go on until one gains < lin_tol."""

    def __init__(self, k, table, path, machine, limits, s0, s1, settings, joins):
        self.k, self.s0, self.s1 = k, s0, s1
        self.options = settings.clarabel()
        self.midpoint_cap = settings.midpoint_cap
        if settings.solver not in ("ipm", "clarabel"):
            raise PlanningError(f"{settings.name}: solver {settings.solver!r} is not 'ipm' or 'clarabel'")
        self.solver = settings.solver
        J, T = limits.joint, machine.servo_period_s
        self.tu = J.a / J.j
        self.lims = (J.v * self.tu, J.a * self.tu ** 2, J.j * self.tu ** 3)
        self.grid = grid_of(path, table, joins, s0, s1, settings.grid_mm, settings.station_radii,
                            settings.knot_stations, settings.station_min_mm)
        sk = np.array([k for k in settings.knot_cells if s0 < k < s1], float)
        if len(sk):
            self.grid = np.unique(np.concatenate([self.grid, sk, sk - KNOT_CELL_MM, sk + KNOT_CELL_MM]))
        if settings.extra_stations:
            self.grid = _with_stations(self.grid, np.asarray(settings.extra_stations, float))
        self.joins = _join_rows(machine, path, self.grid, joins, T / self.tu)
        travel = []
        if settings.join_grading and self.joins:
            travel = self._join_travel(path, limits, T)
            self.grid = _graded(self.grid, [r[0] for r in self.joins], travel)
            self.joins = _join_rows(machine, path, self.grid, joins, T / self.tu)
        self.knot_at = np.searchsorted(self.grid, sk)
        e = np.clip(self.grid, s0 + 1e-9, s1 - 1e-9)        # one-sided at the corners
        cart = cartesian_derivs(path, e)
        cap = feed_cap(path, self.grid, limits, T, kappa=cross_norm(cart[1], cart[2]))
        self.cap2 = (cap * self.tu) ** 2
        self.path_cap2 = self.cap2.copy()          # F_max and the chord-error cap: caps along s
        self.deriv = joint_derivs(machine, path, e, cart=cart, fit_scale=True)
        self.period = T / self.tu
        # the joins whose reads the window rows hold (Settings.window_reads, _window_reads); without,
        # the rows at the graded stations within READ_REACH periods' travel
        self.window_joins = list(self.joins) if settings.window_reads else []
        pointwise = [] if settings.window_reads else [(row, travel[k] if travel else None) for k, row in enumerate(self.joins)]
        if self.window_joins:
            self.sides = _one_sided(self.deriv, self.joins)
        # at a window join's station each side's own jerk ≤ J (the window rows read the jump)
        self.join_reads = [(i, D1, D2, D3, np.zeros(D1.shape[1])) for i, D1, D2, D3, _ in self.window_joins]
        self.join_reads += [row for row, _ in pointwise]
        for (i, *_, kappa), v in pointwise:
            # a third difference at T reads the jump wherever the join lies in its 3-period
            # window, weighted by join_read_weight: graded stations within 1.5 periods' travel
            # (at the join's cap) of a join hold its read too, so weighted, with their own q′,
            # q″, q‴ (without, the SOCP used the whole J there and the repairs at T did not
            # converge on cam_blend_kossel)
            if v is None:
                continue
            d = np.abs(self.grid - self.grid[i]) / max(v, GRADED_MIN_MM)   # periods' travel
            near = np.nonzero((d > 0) & (d < READ_REACH))[0]
            self.join_reads += [(k, *(D[k][None, :] for D in self.deriv[1:]),
                                 kappa * join_read_weight(d[k])) for k in near]
        for i, *_, kappa in (self.joins if self.window_joins else self.join_reads):
            # |κ|ṡ² ≤ 2J, which |jerk| ≤ J and |jerk + κṡ²| ≤ J imply (and a window centred on
            # the join, which reads the jerk's average plus κṡ²)
            self.cap2[i] = min(self.cap2[i], 2 * self.lims[2] / np.abs(kappa).max())
        # per station the fraction of each limit (LIMIT_COLUMNS) it is held to: 1 until the
        # check at T reads the limit above 1 in a window over the station (tighten)
        self.factor = np.ones((len(self.grid), len(LIMIT_COLUMNS)))
        self.times_tightened = np.zeros((len(self.grid), len(LIMIT_COLUMNS)), int)
        self.changed = np.zeros(len(self.grid), bool)
        self.prof = self.span = self.reference = self.relaxed = None
        self.reference_is_coarser = False
        self.stuck = False
        self.insufficient_progress = 0
        self.ipm_fallbacks = 0

    def _join_travel(self, path, limits, T):
        """Per G1 join (self.joins) the travel in one servo period T at its cap (the feed cap
        either side, and the jump's read |κ|ṡ² ≤ 2J alone), in mm."""
        out = []
        for i, *_, kappa in self.joins:
            sj = self.grid[i] + np.array([-1e-7, 1e-7])
            _, P1, P2, _ = cartesian_derivs(path, sj)
            v = float(feed_cap(path, sj, limits, T, kappa=cross_norm(P1, P2)).min())
            if np.abs(kappa).max() > 0:
                v = min(v, math.sqrt(2 * self.lims[2] / np.abs(kappa).max()) / self.tu)
            out.append(v * T)
        return out

    def where(self) -> str:
        return f"piece {self.k} (s = {self.s0:.6g}…{self.s1:.6g} mm)"

    def _limits(self):
        """The joints' v, a, j limits at each station (n × 3), each held to its factor."""
        f = self.factor
        v, a, j = (np.outer(f[:, m], np.full(3, lim)) for m, lim in enumerate(self.lims))
        j[self.knot_at] = KNOT_JERK_FREE * self.lims[2]
        return v, a, j

    def _rows(self, a_lin=None):
        """The TOPP3-SOCP's rows (ipm.Rows), the G1 joins' linearised around a_lin; without
        a_lin, the joints' limits and the caps only (TOPP2-RA's problem)."""
        _, d1, d2, d3 = self.deriv
        v, a, j = self._limits()
        f = self.factor
        rows = ipm.Rows(self.grid - self.s0, d1, d2, d3, v, a, j, self.cap2 * f[:, 3] ** 2)
        if a_lin is None:
            return rows
        for i, D1, D2, D3, kappa in self.join_reads:
            # ±(q‴a + 3q″b + q′c + κ√a) ≤ J/√a: where ±κ > 0, ±κ√a ≥ its tangent at r² = a_lin
            # (≤ the cap); where ±κ ≤ 0, the read is dropped (±jerk ≤ J/√a, the stricter)
            r = math.sqrt(max(min(a_lin[i], self.cap2[i]), 1e-12))
            sg = np.array([1.0, -1.0])[None, :]
            kap = np.maximum(sg * np.broadcast_to(kappa, D1.shape).ravel()[:, None], 0.0)
            ga = sg * D3.ravel()[:, None] + kap / (2 * r)
            rows.add_3rd(ga, sg * 3 * D2.ravel()[:, None], sg * D1.ravel()[:, None], kap * r / 2, j[i, 0], i)
        if self.window_joins:
            self._window_reads(rows, a_lin)
        if self.midpoint_cap:
            # between stations b is linear and a(x) = a_k + 2b_k·x + c·x², so a cell's middle is
            # (3a_k + a_k+1)/4 + b_k·Δ/2 = (a_k + 3a_k+1)/4 − b_k+1·Δ/2.  With the far station within
            # its cap C, the middle is within the mean of the caps either side where
            # a_k + ⅔Δ·b_k ≤ (2C_k + C_k+1)/3, and where a_k+1 − ⅔Δ·b_k+1 ≤ (C_k + 2C_k+1)/3.  Both
            # rows are held: a cell peaks off its middle where a station's slope points out of the
            # cap, which they bound from either side.  Without them b chatters at the cap (±b at
            # alternate stations lifts each middle by |b|Δ/2): the samples at T read F_max 1 + 4e-4
            # along spiral_cone_kossel's cruise.  (A scaled-down feed keeps them: never infeasible.)
            # The caps are the path's (F_max, the chord error): a G1 join's read is a limit of its
            # own stations' samples at T, not of the cells beside them
            C = self.path_cap2 * f[:, 3] ** 2
            d = np.diff(self.grid)
            rows.add_2nd(np.ones(len(d)), 2 * d / 3, (2 * C[:-1] + C[1:]) / 3, 0)
            rows.add_2nd(np.ones(len(d)), -2 * d / 3, (C[:-1] + 2 * C[1:]) / 3, 1)
        return rows

    def _window_reads(self, rows, a_lin):
        """Rows holding every window join's reads at T (Settings.window_reads): the third
        difference of a joint centred c reads ∫q̈(t)·G(t − c)dt, G(τ) = [Λ(τ/T − ½) − Λ(τ/T + ½)]/T²
        (Λ the unit hat: the third difference's kernel, the quadratic B-spline, differentiated
        once onto q̈), and q̈ = q′·s̈ + q″·ṡ² is linear in (a, b) wherever s(t) is known: here the
        time map of a_lin (ṡ linear in time over each cell), so the rows are a linearisation
        like the jerk's tangents.  A jump of q″ (each side's q′, q″ at a join's station) is read
        with its kernel weight, as are the jerk beside it and any other join's jump in the
        window.  Held at every centre c − t_join ∈ READ_CENTRES periods, |read| ≤ J per joint;
        the integral by 2-point Gauss between the kernels' breaks (every ⅛ period from the join)
        and the stations' times (exact where q̈·G is a cubic in t)."""
        g, P = self.grid, self.period
        n = len(g) - 1
        v = np.sqrt(np.maximum(np.asarray(a_lin, float), 0.0))
        dt = 2 * np.diff(g) / np.maximum(v[:-1] + v[1:], 1e-300)
        t = np.concatenate([[0.0], np.cumsum(dt)])
        (R1, R2), (L1, L2) = self.sides
        reach = (READ_CENTRES.max() + 1.5) * P
        breaks = np.arange(-round(reach / P * 8), round(reach / P * 8) + 1) * P / 8
        node, half = np.polynomial.legendre.leggauss(2)
        for i, *_ in self.window_joins:
            lo_t, hi_t = max(t[i] - reach, 0.0), min(t[i] + reach, t[-1])
            k0 = max(int(np.searchsorted(t, lo_t, side="right")) - 1, 0)
            k1 = min(int(np.searchsorted(t, hi_t, side="left")), n)
            bp = np.unique(np.concatenate([t[i] + breaks, t[k0:k1 + 1]]))
            bp = bp[(bp >= lo_t) & (bp <= hi_t)]
            mid, hw = (bp[:-1] + bp[1:]) / 2, np.diff(bp) / 2
            tp = (mid[:, None] + hw[:, None] * node[None, :]).ravel()
            wp = (hw[:, None] * half[None, :]).ravel()
            c = np.clip(np.searchsorted(t, tp, side="right") - 1, 0, n - 1)
            tau, D = tp - t[c], g[c + 1] - g[c]
            x = np.clip(v[c] * tau + (v[c + 1] - v[c]) * tau * tau / (2 * dt[c]), 0.0, D)
            th = (x / D)[:, None]
            q1 = (1 - th) * R1[c] + th * L1[c + 1]
            q2 = (1 - th) * R2[c] + th * L2[c + 1]
            # a(x) = a_c + 2b_c·x + (b_c+1 − b_c)·x²/Δ and b(x) = b_c + (b_c+1 − b_c)·x/Δ
            xx = (x * x / D)[:, None]
            coef = (q2, q2 * (2 * x[:, None] - xx) + q1 * (1 - th), q2 * xx + q1 * th)
            base, width = 2 * k0, 2 * (k1 - k0) + 2
            K = wp[None, :] * second_derivative_kernel(tp[None, :] - (t[i] + READ_CENTRES[:, None] * P), P)
            vals = []
            for m in range(q1.shape[1]):
                M = np.zeros((len(tp), width))
                for col, cf in zip((2 * c, 2 * c + 1, 2 * c + 3), coef):
                    np.add.at(M, (np.arange(len(tp)), col - base), cf[:, m])
                vals.append(K @ M)
            vals = np.concatenate([np.concatenate(vals), -np.concatenate(vals)])
            used = np.flatnonzero(np.abs(vals).max(axis=0) > 0)
            jmax = self.lims[2] * self.factor[k0:k1 + 1, 2].min()
            rows.add_linear(base + used, vals[:, used], np.full(len(vals), jmax))

    def solve(self, settings):
        """(TOPP3 profile, node times in scaled time).  The first time: linearised around
        TOPP2-RA's profile (or the ``reference``), then around each solution (settings.lin_tol,
        .lin_predicted, .max_linearisations);
        after a tightening (``changed``: the stations whose factors moved), the windows around
        them only, from the last solution."""
        if self.prof is not None and not self.stuck:
            try:
                self.prof = self._resolve_windows()
            except copp.CoppError:
                # not even the whole piece had a solution under its tightened limits (Clarabel:
                # (almost) primal infeasible): it keeps its last solution, which the last resort
                # stretches (_stretch), and is not solved again
                self.stuck = True
        if self.prof is None:
            a_lin = np.minimum(self.topp2_ra() if self.reference is None else self.reference, self.cap2)
            # a reference (TOPP2-RA's profile is far above any jerk-limited one) counts as the
            # solve before the first: a first solve that moves its time by < lin_tol is the
            # fixed point a second linearisation would only confirm.  Not a coarser grid's
            # solution: its first solve here moved < lin_tol and stopped 7e-5 above the fixed
            # point on rand_3d_lcnc
            before = None if self.reference is None or self.reference_is_coarser else self._chord_time(a_lin)
            best = start = None
            for _ in range(settings.max_linearisations):
                # each linearisation starts from the last one's iterate (same rows' pattern)
                prof, start = self._socp(self._rows(a_lin), a_lin, start=start)
                prof, tf, ts = self._timed(prof)
                done = (best is not None and (best[0] - tf) / tf < settings.lin_tol) or \
                    (best is None and before is not None and abs(before - self._chord_time(prof.a)) < settings.lin_tol * tf) or \
                    (settings.lin_predicted is not None and linearisation_cost(a_lin, prof.a, ts) < settings.lin_predicted)
                if best is None or tf < best[0]:
                    best = (tf, prof, ts)
                if done:
                    break
                a_lin = prof.a
            self.prof = self.relaxed = best[1]
        self.changed[:] = False
        self.prof, _, ts = self._timed(self.prof)
        return self.prof, ts

    def _chord_time(self, a):
        """Σ 2Δs/(√a_k + √a_k+1) in scaled time: a station profile's time, its b aside."""
        r = np.sqrt(np.maximum(a, 0.0))
        return float(np.sum(2 * np.diff(self.grid) / np.maximum(r[:-1] + r[1:], 1e-300)))

    def topp2_ra(self):
        """a at the stations of the jerk-free time-optimal profile (TOPP2-RA)."""
        prob2 = copp.solver.topp2_ra.Problem(self._rows().copp_robot().constraints, (0, len(self.grid) - 1), (0.0, 0.0))
        return copp.solver.topp2_ra.solve(prob2)

    def _timed(self, prof):
        """(profile, its time, its node times) by copp's time map; where that is NaN, once more
        with s̈ = 0 at the profile's stops inside the piece (_stops_at_rest)."""
        s = self.grid - self.s0
        if prof.a.min() < 0:        # Clarabel's round-off at a stop (a ≈ −1e-9 beside µm cells)
            prof = copp.Profile3rd(np.maximum(prof.a, 0.0), prof.b, prof.num_stationary)
        try:
            tf, ts = copp.interpolation.s_to_t_topp3(s, prof)
        except copp.CoppError as e:
            if "NaN" not in str(e):
                raise
            prof = _stops_at_rest(prof)
            tf, ts = copp.interpolation.s_to_t_topp3(s, prof)
        if not np.isfinite(tf):
            raise copp.CoppError(f"the profile's time is {tf}")
        return prof, tf, ts

    def _resolve_windows(self):
        """The last solution with each window around the changed stations solved again, its
        ends held at that solution's a and b (_windows); a window without a solution is widened
        WINDOW_GROWTH times, up to the whole piece."""
        old = self.prof
        a, b = old.a.copy(), old.b.copy()
        ns = list(old.num_stationary)
        n = len(self.grid)
        rows = self._rows(np.minimum(a, self.cap2 * self.factor[:, 3] ** 2))
        # in scaled time √a is the travel per t_u
        margin = WINDOW_TU * math.sqrt(max(float(a[self.changed].max(initial=0.0)), 0.0))
        # a window solve holds only the window rows' blocks wholly inside it (ipm.solve): one
        # cutting a join's block dropped its reads, and the next round read 1.5–1.8 × J there
        blocks = [(int(cols.min()) // 2, int(cols.max()) // 2) for cols, _, _ in rows.linear]
        for lo, hi in _covering(_windows(self.changed, self.grid, a, margin, WINDOW_STATIONS), blocks):
            while True:
                a_lin = np.minimum(a[lo:hi + 1], self.cap2[lo:hi + 1] * self.factor[lo:hi + 1, 3] ** 2)
                try:
                    # at the piece's ends: the rest it starts and stops at
                    ends = [(a[lo], b[lo]) if lo > 0 else (0.0, 0.0), (a[hi], b[hi]) if hi < n - 1 else (0.0, 0.0)]
                    prof, _ = self._socp(rows, a_lin, lo, (ends[0][0], ends[1][0]), (ends[0][1], ends[1][1]),
                                         (1 if lo == 0 else 0, 1 if hi == n - 1 else 0))
                    break
                except copp.CoppError:
                    if lo == 0 and hi == n - 1:
                        # the whole piece, linearised around the last solution as it was
                        a0 = np.minimum(old.a, self.cap2 * self.factor[:, 3] ** 2)
                        return self._socp(self._rows(a0), a0)[0]
                    w = WINDOW_GROWTH * (hi - lo)
                    (lo, hi), = _covering([(max(lo - w, 0), min(hi + w, n - 1))], blocks)
            a[lo:hi + 1], b[lo:hi + 1] = prof.a, prof.b
            if lo == 0:
                ns[0] = prof.num_stationary[0]
            if hi == n - 1:
                ns[1] = prof.num_stationary[1]
        return copp.Profile3rd(a, b, tuple(ns))

    def _socp(self, rows, a_lin, lo=0, a_ends=(0.0, 0.0), b_ends=(0.0, 0.0), stationary=1, start=None):
        """(TOPP3-SOCP's profile over stations lo … lo + len(a_lin) − 1 of ``rows`` (_rows), the
        IPM's ipm.Start for the next solve of these rows or None), by the banded interior-point
        method (ipm.py; Settings.solver, from ``start`` where given) or copp-py's Clarabel, which also
        takes the rows where the IPM stops without a solution (info["ipm_fallbacks"]); Clarabel's
        last iterate is accepted where it stops on insufficient progress (feeds orders of magnitude
        apart at µm blend arcs next to fast stretches): the check at T judges it like any other."""
        if self.solver == "ipm":
            try:
                sol = ipm.solve(rows, a_lin, lo, a_ends, b_ends, stationary, start)
                return copp.Profile3rd(sol.a, sol.b, sol.num_stationary), sol.start
            except ipm.NoSolution:
                self.ipm_fallbacks += 1
        prob = copp.solver.topp3_socp.Problem(rows.copp_robot().constraints, a_lin, idx_s_start=lo,
                                              a_boundary=a_ends, b_boundary=b_ends, num_stationary_max=stationary)
        res = copp.solver.topp3_socp.solve_expert(prob, self.options)
        if res.profile is None:
            raise copp.CoppError(f"topp3_socp stopped with Clarabel status {res.solver_status}")
        if res.solver_status == copp.core.ClarabelSolverStatus.INSUFFICIENT_PROGRESS:
            self.insufficient_progress += 1
        return res.profile, None

    def tighten(self, col, s_lo, s_hi, ratio, new, extra) -> None:
        """In ``new`` (the next factors): limit ``col`` at the stations under [s_lo, s_hi] and
        one either side held to its present fraction / (ratio·(1 + extra))."""
        g = self.grid
        i0 = max(int(np.searchsorted(g, s_lo, side="right")) - 2, 0)
        i1 = min(int(np.searchsorted(g, s_hi, side="left")) + 2, len(g))
        want = self.factor[i0:i1, col] / (ratio * (1 + extra * 2.0 ** self.times_tightened[i0:i1, col]))
        new[i0:i1, col] = np.minimum(new[i0:i1, col], want)


def linearisation_cost(a_lin, a, ts) -> float:
    """The share of a solution's time the next linearisation is predicted to gain: its jerk rows
    held J/√a by the tangent at a_lin, which lies below J/√a by ε = 1 − √r(3 − r)/2, r = a/a_lin
    (ε ≈ ⅜(r − 1)²; 1 where the tangent is ≤ 0), and a jerk-limited time growing as J^(−⅓): ⅓ of
    ε averaged over the solution's time (its node times ``ts``), as if every station's jerk bound
    (docs/TUNING.md compares it with the next solve's gain)."""
    a_lin, a = np.asarray(a_lin, float), np.asarray(a, float)
    r = np.maximum(a, 0.0) / np.maximum(a_lin, LIN_FLOOR)
    eps = np.clip(1 - np.sqrt(r) * (3 - r) / 2, 0.0, 1.0)
    eps[(a <= 0) | (a_lin <= 0)] = 0.0        # at rest: no jerk row linearised there
    dt = np.diff(np.asarray(ts, float))
    w = np.concatenate([dt, [0.0]]) + np.concatenate([[0.0], dt])
    return float(np.sum(eps * w) / max(3 * np.sum(w), 1e-300))


def _stops_at_rest(prof):
    """The profile with s̈ = 0 where it stops inside the piece (a ≤ STOP_A of its largest a):
    where ṡ touches 0, s̈ is 0, and the solver's round-off there (b slightly below 0 at a ≈ 0 on
    a blend join) made copp's time map NaN."""
    a, b = prof.a, prof.b
    stop = a <= STOP_A * a.max(initial=0.0)
    stop[0] = stop[-1] = False
    if not stop.any():
        return prof
    b = b.copy()
    b[stop] = 0.0
    return copp.Profile3rd(a, b, prof.num_stationary)


def _windows(changed, grid, a, margin_mm, margin_stations):
    """[(first, last station)] covering each run of changed stations and margin_mm (at least
    margin_stations stations) either side, extended out to the next valley of the speed (a
    local minimum of a: a time-optimal profile is on some limit from valley to valley, so a
    window ending inside a braking phase left no room to brake earlier, and an acceleration
    limit tightened there had no solution), overlapping windows merged."""
    idx = np.nonzero(changed)[0]
    n = len(grid)
    if len(idx) == 0:
        return []
    valleys = np.concatenate([[0], np.nonzero((a[1:-1] <= a[:-2]) & (a[1:-1] <= a[2:]))[0] + 1, [n - 1]])
    lo = np.minimum(np.searchsorted(grid, grid[idx] - margin_mm, side="left"), idx - margin_stations)
    hi = np.maximum(np.searchsorted(grid, grid[idx] + margin_mm, side="right") - 1, idx + margin_stations)
    lo = valleys[np.searchsorted(valleys, np.clip(lo, 0, n - 1), side="right") - 1]
    hi = valleys[np.searchsorted(valleys, np.clip(hi, 0, n - 1), side="left")]
    out = [[int(lo[0]), int(hi[0])]]
    for a0, b0 in zip(lo[1:], hi[1:]):
        if a0 <= out[-1][1]:
            out[-1][1] = max(out[-1][1], int(b0))
        else:
            out.append([int(a0), int(b0)])
    return [tuple(w) for w in out]


def _covering(windows, blocks):
    """``windows`` [(first, last station)] each widened until no block (first, last station of
    a join's window rows) lies partly inside it, overlapping windows merged."""
    grown = []
    for lo, hi in windows:
        while True:
            cut = [(b0, b1) for b0, b1 in blocks if b0 <= hi and b1 >= lo and (b0 < lo or b1 > hi)]
            if not cut:
                break
            lo, hi = min([lo] + [b0 for b0, _ in cut]), max([hi] + [b1 for _, b1 in cut])
        grown.append((lo, hi))
    out = []
    for lo, hi in sorted(grown):
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


class _Topp3Span:
    """A solved piece as one piece of `Profile.from_pieces`: s(t) by copp's own inverse of its
    time map; ṡ, s̈, s⃛ from the model: between stations a(x) = a_k + 2b_k·x + (b_{k+1} − b_k)/Δs·x²,
    in the stationary blocks at the ends s − s_end = C·τ³ (copp's constant-jerk start and stop)."""

    def __init__(self, piece, prof, ts):
        self.prof, self.tu, self.ts = prof, piece.tu, ts
        self.s0, self.s = piece.s0, piece.grid - piece.s0
        self.a, self.b, self.ns = prof.a, prof.b, prof.num_stationary

    @property
    def duration(self):
        return float(self.ts[-1]) * self.tu

    def _cubic(self, i_node, s_end, tau):
        """ṡ, s̈, s⃛ of s = s_end + C·τ³ reaching station i_node at its a."""
        C = self.a[i_node] ** 1.5 / (27.0 * (self.s[i_node] - s_end) ** 2)
        return 3 * C * tau ** 2, 6 * C * tau, np.full_like(tau, 6 * C)

    def at(self, tt):
        tu = self.tu
        u = np.clip(np.asarray(tt, float) / tu, 0.0, self.ts[-1])       # scaled time
        uu, inv = np.unique(u, return_inverse=True)                      # copp wants them increasing
        s = copp.interpolation.t_to_s_topp3_samples(self.s, self.prof, self.ts, uu)[inv]
        n = len(self.s) - 1
        k = np.clip(np.searchsorted(self.ts, u, side="right") - 1, 0, n - 1)
        x = s - self.s[k]
        c = (self.b[k + 1] - self.b[k]) / (self.s[k + 1] - self.s[k])
        sd = np.sqrt(np.maximum(self.a[k] + 2 * self.b[k] * x + c * x * x, 0.0))
        sdd, sddd = self.b[k] + c * x, c * sd
        h0, h1 = self.ns
        if h0:
            m = k < h0
            sd[m], sdd[m], sddd[m] = self._cubic(h0, self.s[0], u[m])
        if h1:
            m = k >= n - h1
            sd[m], sdd[m], sddd[m] = self._cubic(n - h1, self.s[-1], u[m] - self.ts[-1])
        return s, sd / tu, sdd / tu ** 2, sddd / tu ** 3


def _solved(piece, settings):
    """piece.solve(settings), a solver's failure as a PlanningError naming the piece."""
    try:
        return piece.solve(settings)
    except (copp.CoppError, ValueError) as e:
        raise PlanningError(f"{settings.name}: no solution of {piece.where()}: {type(e).__name__}: {e}") from None


def _sample(pieces, T, path, info, settings) -> Profile:
    """The pieces solved (those not solved since they were tightened) and sampled at T."""
    for p in pieces:
        if p.span is None:
            p.span = _Topp3Span(p, *_solved(p, settings))
    return Profile.from_pieces(settings.name, T, [p.span for p in pieces], path, info)


def reads_above(prof, machine, path, limits):
    """[(limit column, first sample of the window, its width in samples, ratio)] of every window
    that reads a limit above 1 at T (planners.verify.windows_above): joint v, a, j of the IK'd
    samples, the feed against F_max."""
    column = {"velocity": 0, "acceleration": 1, "jerk": 2, "feed": 3}
    return [(column[o], i, max(column[o], 1), r) for o, i, r in
            windows_above(machine.ik(path.point(prof.s)), prof.T, limits.joint, prof.s, limits.feed_max)]


def _read_limits(limits, slack: float):
    """The limits the samples at T are read against: the joint limits 1 + ``slack`` × wider
    (Settings.read_slack), F_max as it is."""
    return limits.joint_scaled(1 + slack) if slack else limits


def phase_reads(prof, spans, machine, path, limits, phases: int) -> list:
    """[(limit column, s_lo, s_hi, ratio)]: the windows that read a limit above 1 at T
    (reads_above) in ``prof`` and in its ``spans`` sampled with the start delayed by k·T/phases,
    k = 1 … phases − 1, each as the arc lengths it spans."""
    out = []
    for k in range(phases):
        p = prof if k == 0 else Profile.from_pieces(prof.planner, prof.T, [Rest(k * prof.T / phases), *spans], path)
        s = p.s
        out += [(col, s[i], s[min(i + width, len(s) - 1)], r) for col, i, width, r in reads_above(p, machine, path, limits)]
    return out


def _tighten(pieces, above, extra) -> None:
    """Each limit read above at the stations under its window (Piece.tighten; ``above`` as
    phase_reads gives it); the pieces whose factors changed are to be solved again."""
    new = [p.factor.copy() for p in pieces]
    starts = np.array([p.s0 for p in pieces])
    for col, lo, hi, ratio in above:
        for g in range(max(int(np.searchsorted(starts, lo, side="right")) - 1, 0),
                       int(np.searchsorted(starts, hi, side="right"))):
            pieces[g].tighten(col, lo, hi, ratio, new[g], extra)
    for p, f in zip(pieces, new):
        p.times_tightened += f < p.factor
        moved = np.any(p.factor != f, axis=1)
        if moved.any():
            p.factor, p.span = f, None
            p.changed |= moved


def _stretch(prof, rounds, machine, path, limits, info, name) -> Profile:
    """The last resort when MAX_REPAIRS rounds of tightening left windows above a limit
    (``prof``: the last round's samples; ``rounds``: each round's solved pieces): the fastest,
    of those that bring every read within the limits, of each round's profile stretched locally
    around its reads (stretch_locally: a round's tightening costs time everywhere under its
    windows, and a few reads left after round k can cost less to stretch than rounds k + 1 …
    cost to repair) and of the last one's pieces stretched uniformly (_stretch_uniformly; where
    none brings every read within, that one: the harness's check reports it)."""
    best = _stretch_uniformly(prof, rounds[-1], machine, path, limits, info, name)
    fits = not reads_above(best, machine, path, limits)
    for k, spans in enumerate(rounds):
        start = prof if k == len(rounds) - 1 else Profile.from_pieces(name, prof.T, spans, path, info)
        local = stretch_locally(start, spans, machine, path, limits, info, name)
        if local is not None and (not fits or local.info["continuous_time_s"] < best.info["continuous_time_s"]):
            best, fits = local, True
            best.info["local_stretch"]["round"] = k
    return best


def stretch_locally(prof, spans, machine, path, limits, info, name) -> Profile | None:
    """The pieces' time (their solved ``spans``) stretched around each read above by sech bumps
    of whole periods (timewarp.Local), round by round until every sample reads within the
    limits; None where MAX_STRETCHES rounds or MAX_BUMPS bumps did not (or the stretched time
    could not be inverted: timewarp.Local.original).  info["local_stretch"]: the bumps and the
    time they added."""
    T = prof.T
    spans = [timewarp.Local(w, timewarp.bump_width(limits.joint)) for w in spans]
    for _ in range(MAX_STRETCHES):
        Q = machine.ik(path.point(prof.s))
        need = stretch_need(Q, prof.s, T, limits)
        above = np.nonzero(need > 1 + FEASIBLE_TOL)[0]
        if len(above) == 0:
            prof.info["local_stretch"] = {"bumps": int(sum(len(w.c) for w in spans)),
                                          "added_s": round(sum(w.added_s for w in spans), 9)}
            return prof
        widths = timewarp.local_widths(Q, T, limits.joint, above)
        starts = np.concatenate([[0.0], np.cumsum([w.duration for w in spans])])
        g = np.clip(np.searchsorted(starts, prof.t[above], side="right") - 1, 0, len(spans) - 1)
        for k in np.unique(g):
            sel = g == k
            spans[k].add(*timewarp.bumps_for(spans[k], prof.t[above[sel]] - starts[k], need[above[sel]], T,
                                             STRETCH_EXTRA, widths[sel]))
        if sum(len(w.c) for w in spans) > MAX_BUMPS:
            return None
        try:
            prof = Profile.from_pieces(name, T, spans, path, info)
        except ArithmeticError:             # the stretched time's inverse did not converge
            return None
    return None


def _stretch_uniformly(prof, spans, machine, path, limits, info, name) -> Profile:
    """Each piece (its solved ``spans``) with a sample above stretched uniformly in time by the
    worst need there (planners.verify.stretch_need: velocity scales by 1/λ, acceleration 1/λ²,
    jerk 1/λ³), up to MAX_STRETCHES times.  info["stretch"]: each piece's λ."""
    T = prof.T
    spans = [timewarp.Uniform(w) for w in spans]
    for _ in range(MAX_STRETCHES):
        need = stretch_need(machine.ik(path.point(prof.s)), prof.s, T, limits)
        starts = np.concatenate([[0.0], np.cumsum([w.duration for w in spans])])
        g = np.clip(np.searchsorted(starts, prof.t, side="right") - 1, 0, len(spans) - 1)
        worst = np.zeros(len(spans))
        np.maximum.at(worst, g, need)
        if worst.max() <= 1 + FEASIBLE_TOL:
            break
        for w, r in zip(spans, worst):
            if r > 1 + FEASIBLE_TOL:
                w.lam *= r * (1 + STRETCH_EXTRA)
        prof = Profile.from_pieces(name, T, spans, path, info)
    prof.info["stretch"] = [round(w.lam, 6) for w in spans]
    return prof


def pieces_of(path, machine, limits, settings: Settings, stops=()) -> list[Piece]:
    """The path's rest-to-rest pieces as problems on their station grids; ``stops``: arc lengths
    inside them where the profile comes to rest too (pso's near-stops)."""
    check_limits(limits, settings.name)
    check_path(path, settings.name)
    g = settings.grid_mm
    if not (isinstance(g, (int, float)) and not isinstance(g, bool) and 0 < g < math.inf):
        raise PlanningError(f"{settings.name}: grid_mm = {g!r} must be a finite number > 0")
    table = PathTable(path, machine)
    joins = join_jumps(path, table, machine)
    spans = rest_pieces(path)
    if len(stops):
        edges = np.unique(np.concatenate([[s0 for s0, _ in spans], [path.length], np.asarray(stops, float)]))
        spans = list(zip(edges[:-1].tolist(), edges[1:].tolist()))
    return [Piece(k, table, path, machine, limits, s0, s1, settings, joins) for k, (s0, s1) in enumerate(spans)]


def station_time(pieces, settings: Settings) -> float:
    """The pieces solved on their stations alone (the linearisations, no check at T): their
    time in s, what solve() reports as info["station_relaxation_s"] on these stations."""
    return sum(float(_solved(p, settings)[1][-1]) * p.tu for p in pieces)


def linearise_around(pieces, solved) -> None:
    """Each piece's first linearisation around the same piece of ``solved`` (on other stations,
    its first solve's ṡ² by its own model: speed_squared_at): a coarser grid's solution is near
    the finer one's fixed point, so the finer grid takes fewer linearisations than from
    TOPP2-RA's profile (docs/TUNING.md)."""
    for p, q in zip(pieces, solved, strict=True):
        if q.relaxed is not None:
            p.reference = speed_squared_at(q.grid, q.relaxed, p.grid)
            p.reference_is_coarser = True


def speed_squared_at(grid, prof, s):
    """a = ṡ² of a TOPP3 profile on ``grid`` at the arc lengths ``s``, by its own model: between
    stations a(x) = a_k + 2b_k·x + c·x², in the stationary blocks at the ends a ∝ x^(4/3) (copp's
    constant-jerk start and stop, s − s_end = C·τ³), within the range of each cell's two stations
    (a linearisation point no solve has reached is not taken).  Linear in a between a coarse
    grid's stations, the finer grid's first solve started as far from its fixed point as from
    TOPP2-RA where speed_stations split the cells and at rest (docs/TUNING.md)."""
    a, b = np.asarray(prof.a, float), np.asarray(prof.b, float)
    n = len(grid) - 1
    s = np.clip(np.asarray(s, float), grid[0], grid[-1])
    k = np.clip(np.searchsorted(grid, s, side="right") - 1, 0, n - 1)
    x = s - grid[k]
    c = (b[k + 1] - b[k]) / (grid[k + 1] - grid[k])
    out = np.clip(a[k] + 2 * b[k] * x + c * x * x, np.minimum(a[k], a[k + 1]), np.maximum(a[k], a[k + 1]))
    h0, h1 = prof.num_stationary
    if h0:
        m = k < h0
        out[m] = a[h0] * ((s[m] - grid[0]) / (grid[h0] - grid[0])) ** (4 / 3)
    if h1:
        m = k >= n - h1
        out[m] = a[n - h1] * ((grid[-1] - s[m]) / (grid[-1] - grid[n - h1])) ** (4 / 3)
    return out


def solve(path, machine, limits, settings: Settings, pieces: list[Piece] | None = None) -> Profile:
    """The profile of ``settings`` on ``path`` (its ``pieces``, from pieces_of, where given),
    checked at T and repaired (module docstring).  info["station_relaxation_s"]: the pieces'
    time before the first repair, the limits held at the stations only (a bound of this
    transcription, from its local solution)."""
    if pieces is None:
        pieces = pieces_of(path, machine, limits, settings)
    T = machine.servo_period_s
    info = {"pieces": len(pieces), "stations": int(sum(len(p.grid) for p in pieces)),
            "g1_joins": sum(len(p.joins) for p in pieces), "tightened": []}
    read = _read_limits(limits, settings.read_slack)
    rounds = []                 # each round's solved pieces, for the last resort
    for rnd in range(MAX_REPAIRS + 1):
        prof = _sample(pieces, T, path, info, settings)
        if rnd == 0:
            info["station_relaxation_s"] = float(sum(p.span.duration for p in pieces))
        above = phase_reads(prof, [p.span for p in pieces], machine, path, read, settings.read_phases)
        if not above:
            break
        rounds.append([p.span for p in pieces])
        if rnd == MAX_REPAIRS:
            prof = _stretch(prof, rounds, machine, path, read, info, settings.name)
            above = reads_above(prof, machine, path, read)
            break
        # what the round read above: windows per limit, the time before tightening
        info["tightened"].append({"time_s": prof.execution_time_s,
                                  **{c: sum(1 for a in above if a[0] == m) for m, c in enumerate(LIMIT_COLUMNS)}})
        _tighten(pieces, above, TIGHTEN_EXTRA)
    prof.info["station_relaxation_s"] = info["station_relaxation_s"]
    prof.info["above_at_T"] = len(above)
    prof.info["insufficient_progress"] = sum(p.insufficient_progress for p in pieces)
    prof.info["ipm_fallbacks"] = sum(p.ipm_fallbacks for p in pieces)
    prof.info["repair_failed"] = [p.k for p in pieces if p.stuck]
    return prof
