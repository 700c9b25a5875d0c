"""``hwid report DIR``: figures (paper Figs. 9-16, Bode, batch summaries) and one self-contained
HTML page from what the stages wrote into a run directory.

* :mod:`hwid.report.figures`: one plotting function per figure, on plain data, ``ax=None``, returns
  the figure.
* :mod:`hwid.report.html`: reads the run directory (:func:`~hwid.report.html.load_run`), builds the
  figures and tables, writes ``DIR/report/report.html`` (:func:`~hwid.report.html.write_report`).
"""
from hwid.report.html import RunData, load_run, write_report

__all__ = ["RunData", "load_run", "write_report"]
