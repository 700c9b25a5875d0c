"""``hwid report DIR``: figures (paper Figs. 9-16, Bode, batch summaries, the diagnosis) and one
self-contained HTML page from what the stages wrote into a run directory.

* :mod:`hwid.report.rundir`: reads the run directory into a :class:`~hwid.report.rundir.RunData`
  (:func:`~hwid.report.rundir.load_run`), through :mod:`hwid.results` only.
* :mod:`hwid.report.views`: prepares what the figures and tables show (levels, windows, folded
  periods, harmonics).
* :mod:`hwid.report.figures`: one plotting function per figure, on plain data, ``ax=None``, returns
  the figure.
* :mod:`hwid.report.compare_figures`: ``hwid compare``'s figures (the free run per experiment, the
  residual tests as ``resid`` draws them), written by ``hwid compare`` into ``OUT/figures/``.
* :mod:`hwid.report.tables`: the tables as HTML, with the paper's values from :mod:`hwid.paper`.
* :mod:`hwid.report.html`: the page: which figures, their captions, ``DIR/report/report.html``
  (:func:`~hwid.report.html.write_report`).
"""
from hwid.report.html import write_report
from hwid.report.rundir import RunData, load_run

__all__ = ["RunData", "load_run", "write_report"]
