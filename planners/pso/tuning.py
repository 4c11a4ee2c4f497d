"""pso's constants.  The measurements that chose them are in docs/TUNING.md (section pso)."""

DEGREE = 2                   # ṡ quadratic per knot span ⇒ s⃛ piecewise constant, as in an s-curve
MIN_KNOT_GAP_T = 2           # seed switch times < 2 servo periods apart share a knot (see seed_window)
# a G1 join is passed at this fraction of `join_feed` (the optimum passes bird's at 0.99–1.0 of it)
JOIN_FEED_FRACTION = 0.97
# s⃛ = 0 over a first and last knot span this long (normalised time) at a join end of a sub-piece
FLAT_END_SPAN = 0.003
# control points per sub-piece: fewer cannot shape a dip, more converge slower
SUBPIECE_CONTROL_POINTS = 10
# a sub-piece's ends are fixed, so a violation is penalised: duration × max(1, ratio)^PENALTY_POWER
PENALTY_POWER = 4
# a piece with more joins is searched whole only: a swarm per sub-piece costs more than it wins
MAX_JOINS_CUT = 6
# samples per sub-piece (at least one per 8 servo periods of the seed's time there)
SUBPIECE_SAMPLES = 200
# the polish (see polish.py): SLP steps at most, the refinement of each spline, at most this many
# spans a whole piece, samples per span (fewer let the jerk at T read above the limit between
# samples), the share of the worst stretch above which a row enters the LP, rows per coefficient
POLISH_ITERATIONS = 40
POLISH_REFINE = 3
POLISH_MAX_SPANS = 90
POLISH_SAMPLES_PER_SPAN = 16
POLISH_ACTIVE = 0.7
POLISH_ROWS_PER_COEFF = 20
# size bound of a piece (issue 17): above it the basis is held sparse and the piece is not polished
BASIS_MAX_ELEMENTS = 5_000_000
