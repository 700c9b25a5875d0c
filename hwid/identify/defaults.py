"""The defaults of the whole-model fit and of the identification path, in one table.

Each is a setting of an estimator, not a threshold of a verdict; the module that uses it says what
it does and how it was chosen (the references after each). The config's own defaults (degrees,
orders, types) are in :mod:`hwid.config`.
"""

# ------------------------------------------------------------------ the whole fit (hwid.identify.whole)

#: highest degree of h_bar tried by :class:`hwid.identify.whole.WholeModelFit` when built by hand
#: (``identification.whole.max_degree`` sets it from a config)
MAX_DEGREE = 5
#: function evaluations of each descent (:func:`scipy.optimize.least_squares`)
MAX_NFEV = 200

# ------------------------------------------------------------- its variants (whole_rate, whole_clip)

#: the rates the fit with a slew rate starts from: this many, from crossing the input's range in
#: two minutes to crossing it in ten samples (:mod:`hwid.identify.whole_rate`)
RATE_POINTS = 8
#: the least share of the commanded input's range an actuator slewing at a fitted rate must reach
#: for the rate to be kept (:func:`hwid.identify.whole_rate._follows`: the friction damper's 1 Hz log)
FOLLOW_SHARE = 0.5
#: the limits the fit with a clip starts from: this many places of each, from the input's centre
#: to its end, the last beyond the end (no limit on that side) (:mod:`hwid.identify.whole_clip`)
CLIP_POINTS = 5

# ------------------------------------------------------------------ long records (whole_coarse)

#: records of at most this many samples in all are descended on every sample
READ_ALL = 20000
#: the coarse descent reads about this many samples in all
COARSE_SAMPLES = 8000
#: the most function evaluations of the polish on every sample (each with its Jacobian), and the
#: most coarse fits polished
POLISH_NFEV = 20
POLISH_BEST = 4

# ------------------------------------------------------------------ the path (hwid.identify.path)

#: stage 2's sines shrink by this factor while their output rests on a sensor rail, at most
#: RAIL_TRIES times (:func:`hwid.identify.path.sines_off_the_rails`)
RAIL_SHRINK = 0.7
RAIL_TRIES = 3
#: an identified model's own error allowed beside the noise: a mean-square ratio over the floor of
#: up to this (its RMS up to 1.12x the floor). The diagnosis's gap test allows it an identified model
#: (:data:`hwid.diagnose.conclude.ID_MIN_RATIO`), and the two stages' model is fitted again whole
#: only beyond it (:func:`hwid.identify.path.stages_or_whole`): the paper's own plant, its h read on
#: the levels and run a little beyond them by the slowest sine, misses its records by 1.07x over
#: hours of samples, a misfit by the F test that no diagnosis would hold against it
MODEL_ERROR_RATIO = 1.25

#: a whole model started from the two stages' that is a misfit too replaces theirs only where its RMS
#: on the same records is at most this share of theirs (:func:`hwid.identify.path.stages_or_whole`):
#: a model clearly nearer its records, not one that moved within the noise of the comparison
CLEARLY_BETTER = 0.9
