"""The files of a run directory, named in one place: every writer and reader of a run directory
(``hwid run``, ``simulate``, ``identify-*``, ``batch``, ``diagnose``, ``compare``, the report) takes
the name from here."""

#: the experiments as measured (and the truth, for a simulated plant): :func:`hwid.results.write_simulation`
SIMULATION = "simulation.h5"
#: stage 1 (Section 4): :func:`hwid.results.write_nonlinear`
NONLINEAR = "nonlinear.h5"
#: stage 2 (Section 5): :func:`hwid.results.write_linear`
LINEAR = "linear.h5"
#: the whole-model fit, every fitted block included: :func:`hwid.results.write_whole`
WHOLE = "whole.h5"
#: stage 1 from a recorded plant's levels: :func:`hwid.results.write_history`
HISTORY = "history.h5"
#: a Monte Carlo batch: :func:`hwid.results.write_batch`
BATCH = "batch.h5"
#: a diagnosis and its JSON summary: :func:`hwid.results.write_diagnosis`
DIAGNOSIS = "diagnosis.h5"
DIAGNOSIS_JSON = "diagnosis.json"
#: a comparison and its JSON summary: :func:`hwid.results.write_compare`
COMPARE = "compare.h5"
COMPARE_JSON = "compare.json"
#: ``hwid run``'s identification: the route (stages or whole), why, the model and its adequacy
IDENTIFICATION_JSON = "identification.json"
#: an external rig's journalled calls (a rerun after a failure reuses them)
RIG_JOURNAL = "rig_journal"
#: the HTML report's folder
REPORT = "report"

#: every results file a run directory may hold
FILES = (SIMULATION, NONLINEAR, LINEAR, BATCH, DIAGNOSIS, COMPARE, WHOLE, HISTORY)
