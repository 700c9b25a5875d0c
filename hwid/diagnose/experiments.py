"""Validation experiments of the diagnosis, designed to expose the catalogue's effects.

Two sets of the same kinds, with different levels, rates, frequencies, amplitudes and phases:
``fit`` (the effects' parameters are fitted on it) and ``validation`` (the gaps are measured on it,
data the fits never saw). Kinds, and what each exposes:

=============  ====================================================================================
``levels``     staircase up and down over the identification range widened by 15 % (input and
               sensor saturation, curved borders, steady-state mismatches)
``steps``      fast steps of several sizes (rate limit, sensor lag, delay)
``ramp``       triangles at several rates, one experiment per rate (rate limit: trend with rate)
``small``      fine staircases through ``u = 0`` in both directions (input deadzone)
``hold``       one step and a long hold (drift, sensor lag)
``sine``       ``z = A sin(omega t)`` through the model's pre-compensator (Fig. 8) at several
               amplitudes and frequencies up to 16x the bandwidth (resonance, delay, sensor lag)
``broadband``  a random-phase multisine through the pre-compensator, lines log-spaced from
               bandwidth/5 to 30x the bandwidth
=============  ====================================================================================

Every experiment starts with a lead-in (the far end of the range briefly, then its first value at
the other end until G has settled from any state: :func:`lead_time`) that puts the input
nonlinearity on a known border and lets G settle whatever state the rig was left in (parked, homed,
moved by hand, or where the last call ended); the lead-in is never scored. Three validation experiments are repeated at
the end of the session (noise floor, and whether the gap is reproducible). Everything is scaled
from the sim-side model (settling time, bandwidth) and the config (identification range, sine
amplitude), and is deterministic given the config's seed, so a rerun finds its calls in the rig
journal.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from hwid.model import HWModel

# region codes of every sample (``Experiment.region``)
REGIONS = ("lead_in", "levels", "transients", "near reversals", "extremes", "small moves", "dynamic")


@dataclass
class Experiment:
    """One diagnosis experiment: input ``u`` (after the pre-compensator for sines/broadband),
    the pre-compensator's input ``z`` if any, which samples are scored, and labels."""

    name: str
    kind: str
    role: str                         # "fit" | "validation"
    u: np.ndarray
    mask: np.ndarray                  # scored samples (lead-in excluded)
    z: np.ndarray | None = None
    variable: dict = field(default_factory=dict)   # amplitude / rate / omega of the experiment
    repeat_of: str | None = None
    region: np.ndarray | None = None  # int8 codes into REGIONS

    @property
    def n(self) -> int:
        return self.u.size


@dataclass(frozen=True)
class Design:
    """Sizes the experiments are built from."""

    dt: float
    u_lo: float                       # identification range of u
    u_hi: float
    amplitude: float                  # sine amplitude in z (pre-compensator input) units
    settle_s: float
    omega_c: float
    seed: int
    inside: bool = False              # keep every input inside what the model was identified on
    w_lo: float = -np.inf             # identified range of w (stage 1), model units
    w_hi: float = np.inf
    lead_s: float = 0.0               # hold at an experiment's first input before it is scored
    z_centre: float = 0.0             # what the pre-compensated sines swing about (:func:`z_centre`)

    @property
    def lead_hold_s(self) -> float:
        return max(self.lead_s, 1.5 * self.settle_s)

    @property
    def width(self) -> float:
        return self.u_hi - self.u_lo

    @property
    def centre(self) -> float:
        return 0.5 * (self.u_lo + self.u_hi)


def settling_time(model: HWModel) -> float:
    """2 % settling time of G, s (from its slowest pole and its delay)."""
    p = model.linear.poles()
    slow = np.min(np.abs(p.real)) if p.size else np.inf
    return float(4.0 / slow + model.linear.delay) if np.isfinite(slow) and slow > 0 else float(model.linear.delay)


def lead_time(model: HWModel, u_lo: float, u_hi: float, resolution: float = 1e-4) -> float:
    """Seconds G needs, from any state inside the working range, to come within ``resolution`` of
    the output's span of its rest, seen through h (s).

    A rig may start a call anywhere: parked, homed, moved by hand, left mid-move. The initial error
    of w is at most the span of w over the working range; it decays as ``exp(-t / tau)`` with
    ``tau`` G's slowest time constant and reaches the output multiplied by at most ``max |h'|``.
    ``resolution`` 1e-4 of the output span is a 14-bit sensor's step, below any noise floor."""
    p = model.linear.poles()
    slow = float(np.min(np.abs(p.real))) if p.size else np.inf
    if not np.isfinite(slow) or slow <= 0:
        return float(model.linear.delay)
    F, g0 = model.input, float(model.linear.dc_gain)
    u = np.linspace(u_lo, u_hi, 201)
    v = np.concatenate([F.ascending(u), F.descending(u)])
    w = np.linspace(g0 * v.min(), g0 * v.max(), 401)
    y = model.output(w)
    span_w, span_y = float(np.ptp(w)), float(np.ptp(y))
    if span_w <= 0 or span_y <= 0:
        return float(model.linear.delay)
    slope = float(np.max(np.abs(np.gradient(y, w))))
    gain = slope * span_w / (resolution * span_y)
    return float(np.log(max(gain, 1.0)) / slow + model.linear.delay)


def bandwidth(model: HWModel, dt: float) -> float:
    """-3 dB frequency of G/G(0), rad/s (capped below the Nyquist frequency)."""
    G = model.linear
    nyq = np.pi / dt
    w = np.geomspace(1e-4 * nyq, nyq, 2000)
    mag = np.abs(G.freqresp(w) / G.dc_gain)
    below = np.nonzero(mag < 1 / np.sqrt(2))[0]
    return float(w[below[0]]) if below.size else float(0.5 * nyq)


def z_centre(F, u_lo: float, u_hi: float, amplitude: float) -> float:
    """What the pre-compensated sines swing about, in F's output units: 0, as the paper's sines do,
    where ``[-amplitude, amplitude]`` lies inside what F gives over ``[u_lo, u_hi]``; otherwise the
    middle of that range. A model fitted whole may put F's borders anywhere (h takes up the offset:
    one had ``d+ = -3.35`` for a rig whose play sits about 0), and sines about 0 then drive the rig
    three ranges beyond where it was identified."""
    u = np.linspace(u_lo, u_hi, 201)
    v = np.concatenate([F.ascending(u), F.descending(u)])
    v_lo, v_hi = float(np.min(v)), float(np.max(v))
    if not (np.isfinite(v_lo) and np.isfinite(v_hi)) or (v_lo < -amplitude and amplitude < v_hi):
        return 0.0
    return 0.5 * (v_lo + v_hi)


def design_from(cfg, model: HWModel, identified: dict | None = None) -> Design:
    """Scales from the config's protocols and the sim-side model.

    ``identified``: when the model was identified from the same plant, its ranges (``u_range`` of
    the staircase levels, ``w_range`` of stage 1): the experiments then stay inside them, so the gap
    is not the extrapolation of h or F beyond what was identified."""
    dt = cfg.sampling.dt
    st, sn = cfg.protocols.staircase, cfg.protocols.sine
    F = model.input
    if st is not None:
        lv = list(st.levels_up) + list(st.levels_down)
        lo, hi = float(min(lv)), float(max(lv))
    else:
        z = np.array([-sn.amplitude, sn.amplitude, -sn.amplitude])
        u = F.precompensator(np.repeat(z, 3))
        lo, hi = float(u.min()), float(u.max())
    if sn is not None:
        amp = float(sn.amplitude)
    else:
        amp = 0.4 * float(abs(F.ascending(hi) - F.descending(lo)))
    settle = max(settling_time(model), 20 * dt)
    if st is not None:
        # the staircase's hold is the user's own statement of how long the plant takes to settle;
        # a model pole much slower than that (an identified G can put one near 0) is not believed
        settle = min(settle, 2.0 * float(st.hold))
    lead = lead_time(model, lo, hi)
    if st is not None:
        lead = min(lead, 3.0 * float(st.hold))
    zc = z_centre(F, lo, hi, amp)
    if identified:
        w_lo, w_hi = (float(x) for x in identified.get("w_range", (-np.inf, np.inf)))
        return Design(dt, lo, hi, amp, settle, bandwidth(model, dt), int(cfg.seed), True, w_lo, w_hi, lead, zc)
    return Design(dt, lo, hi, amp, settle, bandwidth(model, dt), int(cfg.seed), lead_s=lead, z_centre=zc)


#: the session's first call holds its first input this long (plus a settling time) before its lead-in
OPENING_S = 60.0


def _n(seconds: float, dt: float) -> int:
    return max(int(round(seconds / dt)), 1)


def _levels(values, hold_s, dt) -> np.ndarray:
    return np.repeat(np.asarray(values, float), _n(hold_s, dt))


def _lead_in(d: Design, first: float, far: float) -> np.ndarray:
    """``far`` briefly, then ``first`` until G has settled from any state (:func:`lead_time`). Every
    caller puts ``far`` and ``first`` at opposite ends of the range: the move between them crosses
    the whole play, so the gear ends it against a known border whatever state the rig started the
    call in; and ``u[0]`` is ``far`` itself, so an actuator reset to ``u[0]`` by its driver has no
    way to travel before the move."""
    brief = _n(max(d.settle_s / 4, 20 * d.dt), d.dt)
    return np.concatenate([np.full(brief, far), np.full(_n(d.lead_hold_s, d.dt), first)])


def _exp(d: Design, name, kind, role, body, lead, z=None, zlead=None, **variable) -> Experiment:
    u = np.concatenate([lead, body])
    mask = np.zeros(u.size, bool)
    mask[lead.size:] = True
    if z is not None:
        z = np.concatenate([zlead, z])
    return Experiment(name, kind, role, u, mask, z, variable)


def _precomp(F, z: np.ndarray) -> np.ndarray:
    return F.precompensator(z)


def _z_sweep(d: Design, a: float) -> np.ndarray:
    """``z`` from ``+a`` down to ``-a``: through the pre-compensator F ends on its descending border
    whatever state the rig was in (the move crosses the play when ``2a`` exceeds it)."""
    k = _n(max(d.settle_s / 8, 10 * d.dt), d.dt)
    return d.z_centre + np.concatenate([np.full(k, a), np.linspace(a, -a, k)])


def _sine_exp(d: Design, F, name, role, amp, omega, seed_phase=0.0, times: int = 1) -> Experiment:
    dt = d.dt
    period = 2 * np.pi / omega
    n_lead = _n(max(d.lead_hold_s, period), dt)
    n_body = times * _n(max(2 * period, d.settle_s), dt)
    t = np.arange(n_lead + n_body) * dt
    z = d.z_centre + amp * np.sin(omega * t + seed_phase)
    # the pre-compensator is applied to the whole record, after a sweep from one end to the other
    # that puts F on a known border
    far = _z_sweep(d, 1.05 * max(amp, d.amplitude))
    zz = np.concatenate([far, z])
    u = _precomp(F, zz)
    mask = np.zeros(u.size, bool)
    mask[far.size + n_lead:] = True
    return Experiment(name, "sine", role, u, mask, zz, {"amplitude": float(amp), "omega": float(omega)})


def _multisine(d: Design, rng: np.random.Generator, n: int, rms: float) -> np.ndarray:
    dt = d.dt
    T = n * dt
    w0 = 2 * np.pi / T
    lo = max(d.omega_c / 5, w0)
    hi = min(30 * d.omega_c, np.pi / (5 * dt))
    k = np.unique(np.round(np.geomspace(lo / w0, max(hi / w0, lo / w0 + 1), 40)).astype(int))
    t = np.arange(n) * dt
    ph = rng.uniform(0, 2 * np.pi, k.size)
    z = np.sum(np.sin(np.outer(t, k * w0) + ph), axis=1)
    return z * (rms / np.std(z))


def _uncrossed(F, lo: float, hi: float, width: float) -> tuple[float, float]:
    """Narrow ``[lo, hi]`` to where the model's borders do not cross (beyond, F is undefined)."""
    a = F.slope_up - F.slope_down if F.type == "backlash" else 1 / F.slope_up - 1 / F.slope_down
    if abs(a) < 1e-12:
        return lo, hi
    if F.type == "backlash":
        # S^a (u - d+) <= S^d (u - d-)
        u_x = (F.slope_up * F.d_plus - F.slope_down * F.d_minus) / a
        upper = a > 0
    else:
        # u/S^a + d+ >= u/S^d + d-
        u_x = (F.d_minus - F.d_plus) / a
        upper = a < 0
    margin = 0.05 * width
    if upper and u_x - margin < hi:
        hi = max(u_x - margin, 0.5 * (lo + hi))
    if not upper and u_x + margin > lo:
        lo = min(u_x + margin, 0.5 * (lo + hi))
    return lo, hi


def design(cfg, model: HWModel, d: Design | None = None) -> list[Experiment]:
    """The diagnosis experiments in the order they are run on the plant."""
    d = d or design_from(cfg, model)
    dt, H, W, c = d.dt, d.settle_s, d.width, d.centre
    F = model.input
    # widened by 15 % to reach saturations beyond the identification range; for an identified model
    # the range itself (its extremes still reach a saturation that matters: the identification's
    # own levels went there)
    widen = 0.0 if d.inside else 0.15
    lo, hi = _uncrossed(F, d.u_lo - widen * W, d.u_hi + widen * W, W)
    root = np.random.SeedSequence(d.seed, spawn_key=(zlib.crc32(b"hwid.diagnose"),))
    rng_fit, rng_val = (np.random.default_rng(s) for s in root.spawn(2))
    exps: list[Experiment] = []

    # staircases over the widened range
    for role, n_up in (("fit", 7), ("validation", 6)):
        up = np.linspace(lo, hi, n_up)
        down = up[::-1][1:]
        body = _levels(np.concatenate([up, down]), H, dt)
        exps.append(_exp(d, f"levels_{role}", "levels", role, body, _lead_in(d, up[0], hi)))
    # fast steps of several sizes
    seqs = {"fit": [0.1, 0.9, 0.3, 0.7, 0.0, 1.0, 0.55, 0.45, 0.8],
            "validation": [0.2, 0.95, 0.05, 0.6, 0.4, 0.85, 0.15, 0.5]}
    for role, fr in seqs.items():
        vals = d.u_lo + W * np.asarray(fr)
        exps.append(_exp(d, f"steps_{role}", "steps", role, _levels(vals, H / 2, dt),
                         _lead_in(d, vals[0], d.u_hi)))
    # triangles at several rates, one experiment per rate
    for role, mults in (("fit", (0.2, 1.0)), ("validation", (0.1, 0.5, 2.0))):
        for m in mults:
            rate = W / (H * m)
            n_stroke = _n(W / rate, dt)
            ramp = np.linspace(d.u_lo, d.u_hi, n_stroke)
            hold = _n(H / 2, dt)
            body = np.concatenate([ramp, np.full(hold, d.u_hi), ramp[::-1], np.full(hold, d.u_lo)])
            exps.append(_exp(d, f"ramp_{role}_r{rate:.3g}", "ramp", role, body,
                             _lead_in(d, d.u_lo, d.u_hi), rate=float(rate)))
    # fine staircases through 0 (or the middle of the range when it does not contain 0)
    mid = 0.0 if d.u_lo < 0 < d.u_hi else c
    s = 0.2 * max(abs(d.u_lo - mid), abs(d.u_hi - mid))
    for role, n_lv in (("fit", 7), ("validation", 6)):
        lv = mid + np.linspace(-s, s, n_lv)
        body = np.concatenate([_levels(lv, H / 2, dt), _levels([d.u_hi], H, dt), _levels(lv[::-1], H / 2, dt)])
        exps.append(_exp(d, f"small_{role}", "small", role, body, _lead_in(d, d.u_lo, d.u_hi)))
    # long holds
    for role, (a, b, n_h) in (("fit", (d.u_hi, c - 0.3 * W, 4)), ("validation", (d.u_lo, c + 0.3 * W, 6))):
        exps.append(_exp(d, f"hold_{role}", "hold", role, _levels([b], n_h * H, dt), _lead_in(d, a, -a + 2 * c)))
    # sines through the pre-compensator
    nyq = np.pi / dt
    A, wc = d.amplitude, d.omega_c
    # the fit set reaches the validation set's largest amplitude: a shape fitted on smaller sines
    # (curved borders) was extrapolated to 1.25 A, and left 2.7-6.2x the floor on that sine alone
    plan = {"fit": [(A, 0.5 * wc), (A, 2 * wc), (A, 8 * wc), (0.5 * A, 2 * wc), (1.25 * A, 2 * wc)],
            "validation": [(A, 0.3 * wc), (A, wc), (A, 4 * wc), (A, 16 * wc), (0.5 * A, wc), (1.25 * A, wc)]}
    # inside: sine amplitudes (and the broadband's peaks) within the identified w range, where the
    # pre-compensator and h were identified (the config's amplitude itself was identified in stage 2)
    a_max = min(abs(d.w_lo - d.z_centre), abs(d.w_hi - d.z_centre)) if d.inside else np.inf
    a_max = max(a_max, A) if np.isfinite(a_max) else a_max
    for role, items in plan.items():
        seen = set()
        for amp, w in items:
            amp = min(amp, a_max)
            w = min(w, nyq / 10)
            name = f"sine_{role}_A{amp:.3g}_w{w:.3g}"
            if name in seen:     # the same sine to the names' 3 digits (an amplitude capped at a_max)
                continue
            seen.add(name)
            exps.append(_sine_exp(d, F, name, role, amp, w))
    # broadband
    for role, rng in (("fit", rng_fit), ("validation", rng_val)):
        n = _n(6 * H, dt)
        z = _multisine(d, rng, n, A / 2.5)
        if d.inside:
            z = np.clip(z, -a_max, a_max)
        z = d.z_centre + z
        zl = np.concatenate([_z_sweep(d, 1.05 * A), np.full(_n(d.lead_hold_s, dt), z[0])])
        zz = np.concatenate([zl, z])
        u = _precomp(F, zz)
        mask = np.zeros(u.size, bool)
        mask[zl.size:] = True
        exps.append(Experiment(f"broadband_{role}", "broadband", role, u, mask, zz, {}))
    # with a given model the session opens with a long hold at its first input: whatever ran before
    # may have left an actuator anywhere, and one that slews across the range in a minute gets there
    # before anything is scored (after an identification on the same plant, its records are what
    # ran before, and the model is simulated from them)
    if not d.inside:
        first = exps[0]
        n_open = _n(OPENING_S + d.settle_s, dt)
        first.u = np.concatenate([np.full(n_open, first.u[0]), first.u])
        first.mask = np.concatenate([np.zeros(n_open, bool), first.mask])
        if first.z is not None:
            first.z = np.concatenate([np.full(n_open, first.z[0]), first.z])
    # repeats at the end of the session
    for name in ("levels_validation", "steps_validation", "broadband_validation"):
        e = next(x for x in exps if x.name == name)
        exps.append(Experiment(name + ".repeat", e.kind, "validation", e.u.copy(), e.mask.copy(),
                               None if e.z is None else e.z.copy(), dict(e.variable), repeat_of=name))
    for e in exps:
        e.region = regions(e.u, e.mask, d, e.z)
    return exps


def again(d: Design, model: HWModel, e: Experiment, times: int) -> list[Experiment]:
    """Validation experiment ``e`` run again for ``times`` its scored length
    (:func:`hwid.diagnose.confirm.check`): a sine as one experiment with its lead-in and ``times``
    as many periods; any other experiment ``times`` times over, each with its lead-in."""
    if e.kind == "sine":
        x = _sine_exp(d, model.input, f"{e.name}.again_x{times}", "validation", e.variable["amplitude"],
                      e.variable["omega"], times=times)
        return [x]
    return [Experiment(f"{e.name}.again{k}", e.kind, "validation", e.u.copy(), e.mask.copy(),
                       None if e.z is None else e.z.copy(), dict(e.variable)) for k in range(1, times + 1)]


def regions(u, mask, d: Design, z=None) -> np.ndarray:
    """Label each sample: lead-in, steady levels, transients after a step, near a reversal of the
    input's direction, beyond the identification range (extremes), small moves around 0, or
    continuously moving (dynamic)."""
    u = np.asarray(u, float)
    n = u.size
    out = np.full(n, REGIONS.index("dynamic"), np.int8)
    du = np.diff(u, prepend=u[0])
    moving = np.abs(du) > 1e-12 * max(d.width, 1.0)
    win = _n(d.settle_s / 2, d.dt)
    # samples since the last change of u
    idx = np.arange(n)
    last_change = np.maximum.accumulate(np.where(moving, idx, 0))
    since = idx - last_change
    steady = since >= win
    # a reversal: the direction of the last move differs from the one before; "near" means
    # within half a settling time and before u has moved 10 % of the range from the turning point
    # (so a step across the range is a transient, not a reversal)
    sgn = np.sign(du)
    rev_idx = np.full(n, -10 ** 9)
    u_rev = np.zeros(n)
    prev, last, ur = 0.0, -10 ** 9, 0.0
    for k in np.nonzero(moving)[0]:
        if prev != 0 and sgn[k] != prev:
            last, ur = k, u[k - 1]
        prev = sgn[k]
        rev_idx[k] = last
        u_rev[k] = ur
    rev_idx = np.maximum.accumulate(rev_idx)
    u_rev = u_rev[np.maximum.accumulate(np.where(moving, idx, 0))]
    near_rev = ((idx - rev_idx) < win) & (np.abs(u - u_rev) < 0.1 * d.width)
    stepwise = (np.abs(du) > 0.02 * d.width)
    step_idx = np.maximum.accumulate(np.where(stepwise, idx, -10 ** 9))
    after_step = (idx - step_idx) < win
    out[steady] = REGIONS.index("levels")
    out[after_step & ~steady] = REGIONS.index("transients")
    mid = 0.0 if d.u_lo < 0 < d.u_hi else d.centre
    staircase_like = steady | after_step
    out[staircase_like & (np.abs(u - mid) < 0.15 * 0.5 * d.width)] = REGIONS.index("small moves")
    out[near_rev] = REGIONS.index("near reversals")
    out[(u < d.u_lo - 0.02 * d.width) | (u > d.u_hi + 0.02 * d.width)] = REGIONS.index("extremes")
    if z is not None:
        # through the pre-compensator u jumps across the gap at each reversal of z: label from z
        z = np.asarray(z, float)
        dz = np.diff(z, prepend=z[0])
        zs = np.sign(dz)
        turn = np.zeros(n, bool)
        turn[1:] = (zs[1:] != zs[:-1]) & (zs[1:] != 0) & (zs[:-1] != 0)
        t_idx = np.maximum.accumulate(np.where(turn, idx, -10 ** 9))
        z_at = z[np.clip(t_idx, 0, n - 1)]
        zr = max(np.ptp(z), 1e-12)
        out[:] = REGIONS.index("dynamic")
        out[(t_idx >= 0) & (np.abs(z - z_at) < 0.1 * zr)] = REGIONS.index("near reversals")
        out[(u < d.u_lo - 0.02 * d.width) | (u > d.u_hi + 0.02 * d.width)] = REGIONS.index("extremes")
    out[~np.asarray(mask, bool)] = REGIONS.index("lead_in")
    return out


def run(plant, exps: list[Experiment], progress=None) -> list:
    """Run each experiment on the plant (journalled when the plant has a journal); return records."""
    records = []
    for e in exps:
        r = plant.run(e.name, e.u, z=e.z)
        r.attrs.update({"kind": e.kind, "role": e.role, **{k: float(v) for k, v in e.variable.items()}})
        records.append(r)
        if progress:
            progress(e)
    return records
