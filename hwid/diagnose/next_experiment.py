"""The experiment that would separate effects a log cannot tell apart.

A recorded plant runs no new experiment, so where the validation records leave several catalogue
effects equally good (:func:`hwid.diagnose.verdict.indistinguishable`), the diagnosis proposes one
for the live rig. Candidates are the protocols hwid runs on an external plant (``hwid simulate``
with ``plant.kind: external``): staircases up and down (wide, beyond the logged range; fine, around
its centre; fast, holds of half a settling time), a reversal held at rest (up to the top of the
range, then back down in small held steps: a play holds still until the input has crossed it, a
Dahl friction's pre-sliding moves at once and levels off, an output hysteresis moves by the share
that passes straight), and bare sines at a few multiples of the bandwidth, at the full amplitude
and at a third of it (two amplitudes and rates: a rate-independent loop keeps its width in the
output at every rate, one before G shrinks and turns with G's response).
Each member of the group, with the parameters it was fitted with, is simulated on each candidate;
the candidate kept is the one that needs the least rig time to separate every pair of members:

``n = kappa (2 Z sigma / delta)^2`` scored samples for the paired test of the diagnosis
(:func:`hwid.diagnose.verdict.paired_z`) to reach ``Z = 5`` when one of the two is true, ``delta``
the RMS difference of their predictions on it and ``kappa`` the noise's correlation time; the
protocol is run ``ceil(n / scored samples)`` times.
"""
from __future__ import annotations

import math

import numpy as np

from hwid import protocols

Z_SEPARATE = 5.0
#: Rig time beyond which the proposal says the group cannot be separated in practice (s).
MAX_RIG_SECONDS = 4 * 3600.0


def _staircase_fragment(lo: float, hi: float, n: int, hold: float, dt: float):
    up = np.round(np.linspace(lo, hi, n), 6)
    down = up[::-1]
    runs = [protocols.staircase(up, hold, dt, "up", [up[-1], up[0]]),
            protocols.staircase(down, hold, dt, "down", [up[0], up[-1]])]
    inputs = [s.u for s in runs]
    scored = [np.arange(s.u.size) >= s.starts[0] for s in runs]
    frag = {"staircase": {"levels_up": up.tolist(), "levels_down": down.tolist(), "hold": float(hold)}}
    return frag, inputs, scored


def _sine_fragment(amplitude: float, omega: float, dt: float, periods: int = 4, lead: int = 2):
    s = protocols.sine(amplitude, omega, periods, lead, dt)
    frag = {"sine": {"amplitude": float(amplitude), "frequencies": [float(omega)], "periods": periods,
                     "lead_in_periods": lead}}
    return frag, [s.z], [np.arange(s.z.size) >= s.steady_start]


def candidates(design) -> list[tuple[str, dict, list, list]]:
    """``(name, protocols fragment, inputs, scored masks)`` of every experiment considered."""
    d = design
    W, c, dt, T = d.width, d.centre, d.dt, max(d.settle_s, 10 * d.dt)
    out = [("wide staircase", *_staircase_fragment(c - 0.575 * W, c + 0.575 * W, 9, 2 * T, dt)),
           ("fine staircase", *_staircase_fragment(c - 0.15 * W, c + 0.15 * W, 9, 2 * T, dt)),
           ("fast staircase", *_staircase_fragment(d.u_lo, d.u_hi, 9, max(0.5 * T, 5 * dt), dt)),
           ("reversal held at rest", *_reversal_fragment(d.u_lo, d.u_hi, 2 * T, dt))]
    if d.u_lo < 0.0 < d.u_hi:       # hwid's sines are centred on u = 0
        amp = 0.9 * min(-d.u_lo, d.u_hi)
        for k in (0.3, 1.0, 3.0, 10.0):
            omega = k * d.omega_c
            if omega < 0.25 * np.pi / dt:
                out.append((f"sine at {k:g}x the bandwidth", *_sine_fragment(amp, omega, dt)))
                out.append((f"sine at {k:g}x the bandwidth, a third of the amplitude", *_sine_fragment(amp / 3, omega, dt)))
    return out


def _reversal_fragment(lo: float, hi: float, hold: float, dt: float):
    """Up to ``hi`` in four held steps, then back down in ten steps of 3 % of the range, each held:
    the output's path just after a reversal, at rest."""
    up = np.round(np.linspace(lo, hi, 5), 6)
    down = np.round(hi - 0.03 * (hi - lo) * np.arange(11), 6)
    runs = [protocols.staircase(up, hold, dt, "up", [up[-1], up[0]]),
            protocols.staircase(down, hold, dt, "down", [up[0], up[-1]])]
    frag = {"staircase": {"levels_up": up.tolist(), "levels_down": down.tolist(), "hold": float(hold)}}
    return frag, [r.u for r in runs], [np.arange(r.u.size) >= r.starts[0] for r in runs]


def propose(fitter, members, effects: dict, design, sigma: float, kappa: float) -> dict:
    """The experiment (from :func:`candidates`) that separates ``members`` (candidates of one
    indistinguishable group, each with its fitted ``theta``) in the least rig time."""
    return _propose([c.effect for c in members], [(c.fitted or effects[c.effect], c.theta) for c in members],
                    fitter, design, sigma, kappa)


#: the effects a refit of the model's own play (F's borders) may stand in for
AFTER_GEAR = ("friction", "output_hysteresis")


def propose_against_play(fitter, cand, design, sigma: float, kappa: float) -> dict | None:
    """For a ``friction`` or ``output_hysteresis`` candidate: the experiment that separates it from
    the model without it, F's borders (the gear's own play) and G re-estimated on the same fit data
    (:meth:`hwid.diagnose.rank.EffectFitter.effect_free_spec`); None for another effect or where the
    model was not re-estimated. A friction that holds the load back widens the play an
    identification finds (a Dahl law's Coulomb level of -0.12 came out as 0.12 more play each side
    on a simulated rig), and an output hysteresis is a play the sensor sees: on the records a
    diagnosis has, the model's own play may take either in."""
    if cand.effect not in AFTER_GEAR or cand.fitted is None or cand.theta is None:
        return None
    spec = fitter.effect_free_spec(None)
    if spec is None:
        return None
    return _propose([cand.effect, "the model's own play"], [(cand.fitted, cand.theta), spec],
                    fitter, design, sigma, kappa)


def mode_sines(design, omega_n: float) -> list[tuple[str, dict, list, list]]:
    """Sines at and about a fitted mode's natural frequency ``omega_n`` (0.8, 1 and 1.25 times it),
    each at the full amplitude of :func:`candidates`' sines and at a third of it, below a quarter of
    the Nyquist frequency; empty where the input range does not hold u = 0 (hwid's sines are
    centred on it) or the mode is above that frequency."""
    d = design
    if not (d.u_lo < 0.0 < d.u_hi and np.isfinite(omega_n) and omega_n > 0):
        return []
    amp = 0.9 * min(-d.u_lo, d.u_hi)
    out = []
    for k in (1.0, 0.8, 1.25):
        omega = k * omega_n
        if omega < 0.25 * np.pi / d.dt:
            out.append((f"sine at {k:g}x the fitted mode ({omega:.4g} rad/s)", *_sine_fragment(amp, omega, d.dt)))
            out.append((f"sine at {k:g}x the fitted mode ({omega:.4g} rad/s), a third of the amplitude",
                        *_sine_fragment(amp / 3, omega, d.dt)))
    return out


def propose_mode_sine(fitter, members, design, sigma: float, kappa: float) -> dict | None:
    """For a ``time_delay`` and a ``resonance`` the validation data cannot tell apart (both fitted,
    :mod:`hwid.diagnose.mode_or_delay`): the sine near the resonance's fitted ``omega_n``
    (:func:`mode_sines`) that separates them in the least rig time. A mode above the band rings
    there and a delay only turns the phase, so a sine at the mode is where their predictions part.
    None where no such sine can be run (the range does not hold u = 0, or the mode is beyond a
    quarter of the Nyquist frequency) or a member was not fitted."""
    mode = next((c for c in members if c.effect == "resonance"), None)
    if mode is None or any(c.fitted is None or c.theta is None for c in members):
        return None
    options = mode_sines(design, float(mode.params.get("omega_n", np.nan)))
    if not options:
        return None
    return _propose([c.effect for c in members], [(c.fitted, c.theta) for c in members], fitter, design, sigma,
                    kappa, options)


def _propose(labels, specs, fitter, design, sigma: float, kappa: float, options=None) -> dict:
    """The experiment separating the models ``specs`` (``(effect, theta)`` each, as
    :meth:`hwid.diagnose.rank.EffectFitter.predict_on` takes them) named ``labels``, among
    ``options`` (default :func:`candidates`)."""
    best = None
    for name, frag, inputs, scored in (candidates(design) if options is None else options):
        preds = [fitter.predict_on(eff, theta, inputs) for eff, theta in specs]
        n_scored = int(sum(int(m.sum()) for m in scored))
        seconds = sum(u.size for u in inputs) * design.dt
        deltas = {}
        for i in range(len(specs)):
            for j in range(i + 1, len(specs)):
                diff = np.concatenate([(a - b)[m] for a, b, m in zip(preds[i], preds[j], scored)])
                deltas[f"{labels[i]} vs {labels[j]}"] = float(np.sqrt(np.mean(diff ** 2)))
        worst = min(deltas.values()) if deltas else 0.0
        need = kappa * (2 * Z_SEPARATE * sigma / worst) ** 2 if worst > 0 else math.inf
        runs = max(1, math.ceil(need / max(n_scored, 1))) if math.isfinite(need) else None
        rig = runs * seconds if runs is not None else math.inf
        if best is None or rig < best["rig_seconds"]:
            best = {"name": name, "protocols": frag, "runs": runs, "rig_seconds": rig, "seconds_per_run": seconds,
                    "difference_rms": deltas}
    separable = best is not None and best["rig_seconds"] <= MAX_RIG_SECONDS
    out = {"separates": list(labels), "experiment": best["name"],
           "config": {"sampling": {"dt": design.dt},
                      "plant": {"kind": "external", "callable": "your_driver_module:rig"},
                      "protocols": best["protocols"]},
           "runs": best["runs"], "rig_seconds": best["rig_seconds"] if separable else None,
           "seconds_per_run": best["seconds_per_run"],
           "separable": bool(separable),
           "difference_rms": best["difference_rms"], "noise_floor": float(sigma),
           "units": "the model's input units (value = scale * raw + offset of the recorded config)"}
    worst_pair = min(best["difference_rms"], key=best["difference_rms"].get) if best["difference_rms"] else ""
    out["why"] = (f"the {best['name']} makes the predictions of {worst_pair} differ by "
                  f"{best['difference_rms'].get(worst_pair, 0.0):.3g} RMS against a noise floor of {sigma:.3g}; "
                  + (f"{best['runs']} run(s) ({best['rig_seconds']:.0f} rig-seconds) reach {Z_SEPARATE:g} "
                     "standard deviations" if separable else
                     f"no experiment considered separates them within {MAX_RIG_SECONDS / 3600:.0f} h of rig time"))
    return out
