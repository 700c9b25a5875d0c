"""The diagnosis figures for ``hwid report`` (from :func:`hwid.results.read_diagnosis`'s plain data).

Figures return their ``Figure`` and never show it (the report saves them with the Agg backend).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def _validation(diag):
    return [(n, e) for n, e in diag["experiments"].items() if e["role"] == "validation" and "y_after" in e]


def plot_residual_map(diag, ax=None):
    """The residual map before and after: for every validation experiment (rows), the local RMS
    of the residual over windows of its scored samples, in units of the noise floor (colour).
    Left: the model as given; right: with the verdict's effect added.

    Parameters
    ----------
    diag : dict
        :func:`hwid.results.read_diagnosis` output.
    ax : pair of Axes, optional
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    s = diag["summary"]
    sigma = max(float(s["noise_floor"]), 1e-300)
    rows = _validation(diag)
    nbin = 60
    maps = []
    for _, e in rows:
        m = e["mask"]
        out = []
        for key in ("y_model", "y_after"):
            r = (e["y"] - e[key])[m] / sigma
            edges = np.linspace(0, r.size, nbin + 1).astype(int)
            out.append([np.sqrt(np.mean(r[a:b] ** 2)) if b > a else np.nan for a, b in zip(edges[:-1], edges[1:])])
        maps.append(out)
    maps = np.asarray(maps, float) if maps else np.ones((1, 2, nbin))
    if ax is None:
        fig, ax = plt.subplots(1, 2, figsize=(11, 0.3 * len(rows) + 2), sharey=True, constrained_layout=True)
    else:
        fig = ax[0].figure
    vmax = max(np.nanmax(maps), 2.0)
    norm = LogNorm(vmin=0.5, vmax=vmax)
    im = None
    for k, title in enumerate(("before: model as given", f"after: + {s['verdict']['effect']}")):
        im = ax[k].imshow(np.clip(maps[:, k, :], 0.5, None), aspect="auto", cmap="magma", norm=norm,
                          extent=(0, 1, len(rows) - 0.5, -0.5), interpolation="nearest")
        ax[k].set_title(title)
        ax[k].set_xlabel("fraction of the scored experiment")
    ax[0].set_yticks(range(len(rows)))
    ax[0].set_yticklabels([n for n, _ in rows], fontsize=7)
    fig.colorbar(im, ax=list(ax), label="local RMS gap / noise floor")
    fig.suptitle(f"gap {s['gap_before']:.3g} -> {s['gap_after']:.3g} (noise floor {s['noise_floor']:.3g})")
    return fig


def plot_ranking(diag, ax=None):
    """Explained fraction of the excess gap per catalogue effect (bars), the verdict highlighted,
    the 0.5 threshold of a verdict dashed; candidates whose BIC score is not positive are hatched."""
    import matplotlib.pyplot as plt
    s = diag["summary"]
    cands = s["candidates"]
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 0.35 * len(cands) + 1.5), constrained_layout=True)
    else:
        fig = ax.figure
    names = [c["effect"] for c in cands][::-1]
    vals = [c["explained_fraction"] for c in cands][::-1]
    win = s["verdict"]["effect"]
    colors = ["tab:red" if n == win else "tab:gray" for n in names]
    bars = ax.barh(names, vals, color=colors)
    for b, c in zip(bars, cands[::-1]):
        if c["score"] <= 0:
            b.set_hatch("//")
    ax.axvline(0.5, ls="--", color="k", lw=0.8)
    ax.set_xlim(0, 1.05)
    ax.set_xlabel("explained fraction of the gap above the noise floor (validation data)")
    ax.set_title(f"verdict: {win} ({s['verdict']['block']})")
    return fig
