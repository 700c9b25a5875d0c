"""The diagnosis's result from its steps (:func:`hwid.diagnose.conclude.conclude`): the verdict's block,
where the gap lies, every candidate and test as :class:`~hwid.diagnose.result.DiagnosisResult`, and
``diagnosis.h5``. ``val`` is the diagnosis's :class:`hwid.diagnose.context.Validation`."""
from __future__ import annotations

from hwid.diagnose import gap
from hwid.diagnose.effects import BLOCK
from hwid.diagnose.floor_lines import with_floor_items
from hwid.diagnose.result import DiagnosisResult
from hwid.diagnose.verdict import Candidate
from hwid.results import write_diagnosis


def where_block(verdict_effect, cands, floor, regions, drift_ok=False) -> str:
    """The block the gap is attributed to: the verdict's; for ``unexplained``, ``noise`` when the
    plant does not repeat itself (not a fixed map from u to y), else the block of the best partial
    explanation, else where the excess lies (levels: output; dynamics only: linear)."""
    if verdict_effect == "none":
        return "none"
    if verdict_effect in BLOCK:
        return BLOCK[verdict_effect]
    if floor.slow_z > 10:
        return "noise"
    eligible = [c for c in cands if c.effect != "drift" or drift_ok]
    best = eligible[0] if eligible else None
    if best is not None and best.explained_fraction >= 0.2:
        return best.block
    levels = regions.get("levels", {}).get("gap_over_noise", 1.0)
    dynamic = max(regions.get(k, {}).get("gap_over_noise", 1.0) for k in ("dynamic", "transients", "near reversals"))
    return "linear" if levels < 1.2 and dynamic > 1.5 else "output" if levels >= 1.2 else "input"


def result_after(verdict, val, res_before) -> list:
    """The validation residuals with the verdict's effect added (the residuals before, without one)."""
    if isinstance(verdict, Candidate):
        return [y - x for y, x in zip(val.y_val, verdict.predictions)]
    return res_before


def build(cfg, val, verdict, cands, res_before, gap_before, gap_ref, floor, test, additive, drift_ok, fitter,
            id_err, by_effect, sim_model, origin, cost, groups=()) -> DiagnosisResult:
    """The result of a diagnosis that ended in ``verdict`` (a :class:`Candidate`, ``"none"`` or
    ``"unexplained"``), from what its steps found."""
    alike: list = []
    if isinstance(verdict, Candidate):
        name, explained, gap_after = verdict.effect, verdict.explained_fraction, verdict.gap_after
        alike = next(([e for e in g["effects"] if e != name] for g in groups if name in g["effects"]), [])
    else:
        name, explained, gap_after = verdict, 0.0, gap_before
    res_after = result_after(verdict, val, res_before)
    val_exps = [val.exps[i] for i in val.val_idx]
    regions_before = gap.per_region([r[e.mask] for r, e in zip(res_before, val_exps)],
                                    [e.region[e.mask] for e in val_exps], floor.sigma)
    where = {
        "experiments": per_experiment(val_exps, res_before, res_after, floor.sigma),
        "region": gap.main_region(regions_before) if test.significant else "nowhere (gap is noise)",
        "frequencies": gap.frequencies(val_exps, res_before, floor, val.design.dt) if test.significant else [],
        "trend": "none (gap is noise)",
        "regions": regions_before,
        "repeatability": {"slow_rms": floor.slow_rms, "slow_z": floor.slow_z, "repeats_differ": bool(floor.slow_z > 10),
                          "difference_follows_output": additive["output_share"],
                          "fast_difference_follows_output": additive["fast_share"], "additive": additive["additive"],
                          "motion_share": additive.get("motion_share", float("nan"))},
    }
    for key in ("slow_z_validation", "motion_share_held"):
        if key in additive:
            where["repeatability"][key] = additive[key]
    if test.significant:
        trend = gap.trend(val_exps, res_before, floor.sigma, val.design.dt)
        where["trend"], where["trend_families"] = trend["trend"], trend["families"]
    design = val.design
    return DiagnosisResult(
        verdict={"effect": name, "block": where_block(name, cands, floor, regions_before, drift_ok),
                 "explained_fraction": float(explained), "indistinguishable_from": alike},
        gap_before=float(gap_before), gap_after=float(gap_after), noise_floor=float(floor.sigma),
        gap_model_refit=float(gap_ref),
        model_refit=({**fitter.model_dict(fitter.g_p),
                      "modes_taken_out": [{"omega_n": w, "zeta": z} for w, z in fitter.modes],
                      "excess_phase_taken_out_s": float(fitter.delay_hint),
                      "slow_pairs_taken_out": [{"pole": p, "zero": z} for p, z in fitter.cancelled_pairs]}
                     if fitter.refit_g else None),
        where=where,
        candidates=[{**c.to_dict(), "eligible": bool(c.effect != "drift" or drift_ok)} for c in cands],
        test={**test.to_dict(), "identification_error": id_err, "by_effect": by_effect},
        noise=floor.to_dict(),
        model={**origin, **sim_model.to_dict()},
        design={"settle_s": design.settle_s, "omega_c": design.omega_c, "u_range": [design.u_lo, design.u_hi],
                "amplitude": design.amplitude, "experiments": [e.name for e in val.exps]},
        cost=dict(cost),
        residual_structure=with_floor_items(val.remainder, floor) if name == "unexplained" else [],
        indistinguishable=list(groups))


def per_experiment(exps, res_before, res_after, sigma) -> list[dict]:
    """Each validation experiment's gap before and after the verdict, largest before first."""
    out = []
    for e, before, after in zip(exps, res_before, res_after):
        gap_b, gap_a = gap.rms(before[e.mask]), gap.rms(after[e.mask])
        out.append({"name": e.name, "kind": e.kind, "gap_before": gap_b, "gap_after": gap_a,
                    "before_over_noise": gap_b / sigma, "after_over_noise": gap_a / sigma, **e.variable})
    out.sort(key=lambda x: -x["before_over_noise"])
    return out


def write_h5(path, cfg, summary, val, res_after, starts=None) -> None:
    """``diagnosis.h5`` through :func:`hwid.results.write_diagnosis`: each experiment's input, the
    plant's output, the model's (before) and, for validation experiments, the model's with the
    leading effect added (after) and, with ``starts`` (:func:`hwid.diagnose.corrected.starts_after`),
    where ``corrected.yaml``'s model starts to give it."""
    starts = starts or {}
    start_of = {i: starts.get(j) for j, i in enumerate(val.val_idx)}
    x_model = {i: val.sim_fit.x[j] for j, i in enumerate(val.fit_idx)}
    x_model.update({i: val.sim_val.x[j] for j, i in enumerate(val.val_idx)})
    after = {i: val.records[i].y - res_after[j] for j, i in enumerate(val.val_idx)}
    rows = [{"name": e.name, "u": r.u, "y": r.y, "y_model": x_model[i], "mask": e.mask, "region": e.region,
             "z": e.z, "y_after": after.get(i), "dt": r.dt, "kind": e.kind, "role": e.role,
             "repeat_of": e.repeat_of, "variable": e.variable, "start_after": start_of.get(i)}
            for i, (e, r) in enumerate(zip(val.exps, val.records))]
    write_diagnosis(path, cfg, summary, rows)
