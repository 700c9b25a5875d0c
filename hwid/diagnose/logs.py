"""``hwid diagnose`` on a recorded plant: the diagnosis from logs alone.

No new experiment can be run, so the diagnosis works with what the records hold:

1. **Split** into fit and validation parts: by experiment where the records hold several (every
   other usable one to validation, in recorded order), by interleaved time blocks where they hold
   one (blocks of at least four settling times, odd ones to validation). Each record's unknown
   start is burnt in: its samples are scored nowhere until the input has spanned the model's play
   and G has then settled 1.5 times. Where that would leave no fit or no validation part (a slow
   plant, short records), each record's start is estimated through the model instead (the gear's
   place in the play, G's rest level) and put before it as a short pre-input
   (:mod:`hwid.diagnose.starts`), every sample then scored; which records, in ``data.starts``.
2. **Model**: ``--model``, or the whole-model output-error fit (:mod:`hwid.identify.whole`, each
   record's initial gear and G state estimated) on the fit parts alone, written to ``whole.h5``.
3. **Noise floor** (:mod:`hwid.diagnose.gap`): from repeated experiments (identical inputs) where
   the records hold them; else from the settled parts of held inputs; else from the high-frequency
   part of the model's residual; never below the output's resolution ``q / sqrt(12)``, never above
   the output's own spread (:func:`hwid.diagnose.from_logs.bounded_floor`). Which one is said in
   the JSON (``data.noise_source``).
4. The effects fitted and ranked as for a live rig (:func:`hwid.diagnose.conclude.conclude`, from
   :func:`hwid.diagnose.from_logs.diagnose_recorded`), with the
   groups the validation data cannot tell apart (``indistinguishable``) and, for the leading group,
   the experiment on the live rig that would (:mod:`hwid.diagnose.next_experiment`).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from hwid import HwidError, spectral_lines
from hwid.diagnose import experiments, gap
from hwid.identify.split import MIN_SCORED
from hwid.recorded import level_segments


def step_settling_time(model, share: float = 0.02) -> float:
    """Seconds until G's step response stays within ``share`` of its final value (s).

    Unlike the slowest pole's ``4 / |Re p|`` (:func:`hwid.diagnose.experiments.settling_time`), this
    weighs each mode by its residue: a slow pole nearly cancelled by a zero (which an output-error
    fit may place to absorb an offset between records) moves the step by less than ``share`` and
    does not make every record's start unusable."""
    from scipy import signal
    G = model.linear
    T = experiments.settling_time(model) - float(G.delay)
    g0 = float(G.dc_gain)
    if not np.isfinite(T) or T <= 0 or g0 == 0:
        return experiments.settling_time(model)
    t = np.linspace(0.0, T, 4001)
    _, s = signal.step((np.asarray(G.num, float), np.asarray(G.den, float)), T=t)
    outside = np.flatnonzero(np.abs(s - g0) > share * abs(g0))
    return float((t[outside[-1]] if outside.size else 0.0) + G.delay)


def known_from(u: np.ndarray, F, settle_samples: int) -> int:
    """First sample at which the model's state no longer depends on the record's unknown start:
    the input has spanned F's play (the gear has met a border whatever its start) and G has then
    had ``settle_samples`` to forget its own start. ``u.size`` if the input never spans the play."""
    width = abs(float(F.d_plus - F.d_minus)) * (1.0 if F.type == "backlash" else 1.0 / max(F.slope_down, 1e-9))
    u = np.asarray(u, float)
    if u.size == 0:
        return 0
    spanned = np.flatnonzero(np.maximum.accumulate(u) - np.minimum.accumulate(u) > width)
    if spanned.size == 0:
        return int(u.size)
    return int(min(u.size, spanned[0] + settle_samples))


#: The band of an identified G's own lightly damped modes, rad/s, for a model identified from logs:
#: none. No sine band fixed part of G; the whole fit put every mode there from the same records, so
#: a lightly damped pair anywhere is the catalogue's ``resonance``, taken out of the refit baseline
#: and left to that effect to earn back on the validation part (a resonance at 6.8 rad/s, zeta 0.13,
#: went into the whole fit's G and was called ``none`` on a blind lab log).
NO_BAND = (0.0, 0.0)


def with_starts(parts, model, dt: float, settle_s: float, echo, identified: bool = False) -> tuple[list, dict]:
    """:func:`plan`'s parts as ``(record, role, samples, scored)``, each record's unknown start
    dealt with: burnt in (``scored`` false up to :func:`known_from` with 1.5 settling times); or,
    where the burn-in would leave the records no fit or no validation part of :data:`MIN_SCORED`
    samples (a slow plant, short records, an input that never spans the play of a model
    ``identified`` from the log), estimated through ``model`` and put before every record as
    :data:`hwid.diagnose.starts.PRE` samples that are never scored (:mod:`hwid.diagnose.starts`). A
    given model whose play no record spans is an error (exit 2). Returns the parts and the estimated
    starts by record name (``level``, ``gear``, and the rms of the record's opening from the default
    start and from the estimated one).

    The burn-in is preferred where it is affordable: an estimated start is fitted by the model
    without the effect, and an effect that shows in a record's opening would be partly absorbed
    into it. An estimated start is fitted on the record's opening only (until the input has
    spanned the play and G has settled once more), where it still shows: what an unmodelled effect
    does later in the record does not move it."""
    from hwid.diagnose import starts
    burn = max(int(round(1.5 * settle_s / dt)), 1)
    out = []
    for r, role, samples in parts:
        scored = samples.copy()
        scored[:known_from(r.u, model.input, burn)] = False
        out.append((r, role, samples, scored))
    if all(any(p[3].sum() >= MIN_SCORED for p in out if p[1] == role) for role in ("fit", "validation")):
        return out, {}
    if all(known_from(r.u, model.input, 0) >= r.u.size for r, _, _, _ in out):
        if not identified:
            raise HwidError("diagnose: no record's input spans the model's play: nothing in the log moves the gear "
                            "from one border to the other, so nothing tells where it is; record a run that does")
        # a play identified wider than everything the log drives: the data did not determine it, and
        # the diagnosis's check of the model on its records reports how far it is off (model_check)
        echo("no record's input spans the identified model's play (the log cannot have determined it): each "
             "record's start is fitted through the model over the whole record")
    settle = max(int(round(settle_s / dt)), 1)
    new, found = {}, {}
    for r, _, _, _ in out:
        if id(r) in new:
            continue
        st = starts.estimate(model, r.u, r.y, dt, known_from(r.u, model.input, settle) + settle)
        new[id(r)] = replace(r, u=np.r_[st["pre"], r.u], y=np.r_[np.full(starts.PRE, r.y[0]), r.y],
                             attrs={**r.attrs, "pre": starts.PRE})
        found[r.name] = {k: st[k] for k in ("level", "gear", "rms_before", "rms_after")}
    echo(f"burning in each record's start (the input spanning the play, then {1.5 * settle_s:.3g} s for G) "
         f"would leave no fit or no validation part of {MIN_SCORED} samples: each start estimated instead "
         "(G's rest level, the gear's place); the opening's rms from the default start -> from the estimate: " +
         ", ".join(f"{k} {v['rms_before']:.3g} -> {v['rms_after']:.3g}" for k, v in found.items()))
    pad = np.zeros(starts.PRE, bool)
    return [(new[id(r)], role, np.r_[pad, samples], np.r_[pad, samples]) for r, role, samples, _ in out], found


def split(parts, design) -> tuple[list, list]:
    """The diagnosis's experiments from :func:`with_starts`'s parts: ``(experiments, records)``;
    a record split in blocks appears twice, once per role, with complementary masks."""
    exps, recs = [], []
    for r, role, samples, scored in parts:
        if scored.sum() < MIN_SCORED:
            continue
        name = r.name if samples[int(r.attrs.get("pre", 0)):].all() else f"{r.name}:{role}"
        e = experiments.Experiment(name, "recorded", role, np.asarray(r.u, float), scored.copy())
        e.region = experiments.regions(e.u, scored, design)
        exps.append(e)
        recs.append(r)
    return exps, recs


def history(recs, records) -> list:
    """The input the rig received before each of ``recs`` as far as the log shows it: the earlier
    pieces of the same file (a logger pause splits a record, :func:`hwid.recorded.load_records`), in
    order; None for a file's first piece and for a record whose start was estimated (its virtual
    pre-input stands for the state instead, :mod:`hwid.diagnose.starts`).

    An actuator with memory carries its position across the pause: a slow slew (a rate limit that
    needs seconds to cross the range) is still far from a piece's first input when the piece begins,
    and started there it misses every sample until it catches up (a rate limit of 0.23 units/s left
    11x the floor from a blind lab log). The effect weighs the carried run against a fresh start
    (:class:`hwid.diagnose.effects.RateLimit`'s ``carried``), so a rig that was reset in the pause
    loses nothing; the gear and G after it restart from where the actuator last crossed the play
    (``lead`` 0), since nothing tells how long the pause held them."""
    out = []
    for r in recs:
        src, piece = r.attrs.get("source_file"), r.attrs.get("piece")
        if int(r.attrs.get("pre", 0)) or src is None or not piece:
            out.append(None)
            continue
        earlier = sorted((q for q in records if q.attrs.get("source_file") == src
                          and q.attrs.get("piece") is not None and q.attrs["piece"] < piece),
                         key=lambda q: q.attrs["piece"])
        out.append(np.concatenate([q.u for q in earlier]) if earlier else None)
    return out


def identify_from_logs(cfg, records, out: Path, echo) -> tuple:
    """The model from logs, by the one identification path (:func:`hwid.identify.path.identify`:
    the records split as :func:`plan` splits them, the whole fit on the fit part, ``whole.h5``),
    taken as the diagnosis's baseline (:func:`hwid.diagnose.sim_side.origin_of`) without G's slow
    pairs (:func:`without_slow_pairs`); the model and its origin."""
    from hwid.diagnose.sim_side import origin_of
    from hwid.identify.path import identify
    ident = identify(cfg, records=records, out_dir=out, echo=echo, stage_results=False)
    echo(f"identified the model by the {ident.route} route: {ident.why}")
    model, origin = origin_of(ident, echo)
    model, notes = without_slow_pairs(model, 2 * np.pi / max(p.u.size * p.dt for p in ident.records), echo,
                                      "the records (2 pi / their longest)")
    origin["notes"] = list(origin.get("notes", [])) + notes
    return model, origin


def without_slow_pairs(model, lo: float, echo, what: str = "the records") -> tuple:
    """The model with the pole-zero pairs of G that nearly cancel below ``lo`` rad/s taken out
    (:func:`hwid.diagnose.baseline.cancel_slow_pairs`), ``(model, notes)``. From logs, ``lo`` is
    ``2 pi`` over the longest record: no record is long enough to place them, and an output-error
    fit puts one there to absorb what an effect does to the levels; left in, its creep would make
    every record's start unusable. For a live rig, the lowest sine that identified G: below it the
    pairs are artefacts of harmonics an effect distorted, and left in they would set the validation
    experiments' length. The diagnosis's refit of h carries the gain."""
    from hwid.blocks.linear import LinearBlock
    from hwid.diagnose.baseline import cancel_slow_pairs
    from hwid.model import HWModel
    G = model.linear
    num, den, pairs = cancel_slow_pairs(G.num, G.den, (lo, np.inf))
    if not pairs:
        return model, []
    note = (f"G had pole-zero pairs below what {what} can place ({lo:.3g} rad/s), taken out: " +
            ", ".join(f"pole {p:.3g} / zero {z:.3g} rad/s" for p, z in pairs))
    echo(note)
    return HWModel(model.input, LinearBlock(tuple(np.asarray(num, float).tolist()),
                                            tuple(np.asarray(den, float).tolist()), G.delay), model.output,
                   model.actuator), [note]


#: the source of a floor from the model's own residual (:func:`floor_from_logs`)
RESIDUAL_FLOOR = "residual high-frequency part"


def floor_from_logs(exps, recs, xs, F, design) -> tuple:
    """The noise floor, its source, and the repeat pairs ``(y, y_repeat, mask)`` (empty without
    repeats); the floor is never below the output's resolution ``q / sqrt(12)``. ``xs``: the
    model's output on each experiment; ``F``: its input nonlinearity."""
    width = max(int(round(2 * design.settle_s / design.dt)), 20)
    y_scale = float(np.ptp(np.concatenate([r.y for r in recs])))
    distinct = list({id(r): r for r in recs}.values())
    pairs = []
    for i, a in enumerate(distinct):
        ka = int(a.attrs.get("pre", 0))
        for b in distinct[i + 1:]:
            kb = int(b.attrs.get("pre", 0))
            ua, ub = a.u[ka:], b.u[kb:]
            if ua.size == ub.size and ua.size >= MIN_SCORED and np.allclose(ua, ub, rtol=0, atol=1e-9):
                mask = np.zeros(ua.size, bool)
                mask[max(known_from(ua, F, width // 2), 0):] = True
                pairs.append((a.y[ka:], b.y[kb:], mask))
    if pairs:
        floor, source = gap.noise_floor(pairs, width, y_scale, design.dt), "repeats"
    else:
        held = holds_floor(exps, recs, xs, design)
        if held is not None:
            floor, n_repeats, n_levels = held
            source = "settled holds"
            if n_repeats:
                source += f" ({n_repeats} of them repeats of {n_levels} level(s))"
        else:
            res = [(r.y - x)[e.mask] for e, r, x in zip(exps, recs, xs)]
            floor, source = gap.noise_floor_from_residual(res, y_scale), RESIDUAL_FLOOR
    quanta = [float(r.attrs.get("output_resolution", 0.0) or 0.0) for r in distinct]
    q = max(quanta) if quanta else 0.0
    if q > 0 and floor.sigma < q / np.sqrt(12.0):
        floor = replace(floor, sigma=float(q / np.sqrt(12.0)))
        source += f" (raised to the output resolution {q:.4g} / sqrt(12))"
    return floor, source, pairs


def holds_floor(exps, recs, xs, design):
    """The noise floor from the settled parts of held inputs (:func:`hwid.diagnose.gap.noise_floor_from_holds`)
    with the model output ``xs`` on each experiment: its residual there, and whether the plant
    wanders at a constant input where the model is still or differs between holds where the model
    puts it in the same state. Returns ``(floor, repeated holds, levels repeated)``, or None where
    no hold is long enough."""
    settle = max(int(round(design.settle_s / design.dt)), 1)
    y_scale = float(np.ptp(np.concatenate([r.y for r in recs])))
    distinct = list({id(r): r for r in recs}.values())
    x_of = {}
    for e, r, x in zip(exps, recs, xs):
        known = x_of.get(id(r), (None, np.zeros(r.u.size, bool)))[1] | e.mask
        x_of[id(r)] = (x, known)
    residual, record_lines = _residuals_without_lines(distinct, x_of, design.dt)
    holds, tails, keys = [], [], []
    span = max(float(np.ptp(np.concatenate([x for x, _ in x_of.values()]))), 1e-12)
    for r in distinct:
        if id(r) not in x_of:
            continue
        x, known = x_of[id(r)]
        for seg in level_segments(np.asarray(r.u, float)):
            a, b = seg["start"], seg["stop"]
            a = max(a + settle, (a + b) // 2)
            if b - a < 40 or not known[a:b].all():
                continue
            res = residual[id(r)][a:b]
            holds.append(res)
            tails.append(x[a:b] - x[b - 1])
            # the model's settled output at the hold's end, to a thousandth of its span: the
            # same state of the plant where the model is in the same state
            keys.append((round(seg["value"], 9), round(float(x[b - 1]) / span, 3)))
    if not holds:
        return None
    # a disturbance at a frequency of its own is no noise and no wander: out of every hold first
    holds, lines = spectral_lines.find_lines(holds, design.dt)
    keyed = {}
    for key, res in zip(keys, holds):
        keyed.setdefault(key, []).append(res)
    repeats = [g for g in keyed.values() if len(g) >= 2]
    # whether the plant wanders at a constant input, where the model is still (within a quarter of
    # the noise of its end): what the plant does while the model still moves is the model's to explain
    first = gap.noise_floor_from_holds(holds, y_scale)
    still = []
    for res, tail in zip(holds, tails):
        moving = np.flatnonzero(np.abs(tail) > 0.25 * first.sigma)
        still.append(res[int(moving[-1]) + 1 if moving.size else 0:])
    floor = replace(gap.noise_floor_from_holds(holds, y_scale, repeats, still=still),
                    lines=tuple(record_lines) + tuple(lines))
    return floor, sum(len(g) for g in repeats), len(repeats)


def _residuals_without_lines(records, x_of: dict, dt: float) -> tuple[dict, list]:
    """Each record's residual ``y - x`` (``x_of[id(record)] = (x, known)``), with the narrow-band
    components of its known samples that its input does not drive taken out
    (:func:`hwid.spectral_lines.find_lines` with the input: a load at a frequency of its own runs on
    through a whole record, phase-continuous, where one hold is too short to show it), and those
    components."""
    out, pieces, inputs, owners = {}, [], [], []
    for r in records:
        if id(r) not in x_of:
            continue
        x, known = x_of[id(r)]
        out[id(r)] = np.asarray(r.y, float) - x
        idx = np.flatnonzero(known)
        if idx.size:
            pieces.append((idx, out[id(r)][idx]))
            inputs.append((idx, np.asarray(r.u, float)[idx]))
            owners.append(id(r))
    if not pieces:
        return out, []
    cleaned, lines = spectral_lines.find_lines(pieces, dt, inputs=inputs)
    for owner, (idx, _), values in zip(owners, pieces, cleaned):
        out[owner][idx] = values
    return out, lines
