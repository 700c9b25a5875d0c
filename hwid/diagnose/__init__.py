"""``hwid diagnose``: where and why a plant and a model part, and what to add to the simulator.

The "real" side is the plant of the config (usually ``plant.kind: external``); the "sim" side is a
model (:mod:`hwid.diagnose.sim_side`): a plant YAML (``kind: hammerstein_wiener``), a directory
written by ``hwid run``, or, when none is given, the model hwid identifies from the same plant.

Steps (:func:`diagnose`, in :mod:`hwid.diagnose.run`):

1. run validation experiments of the diagnosis's own design on the plant
   (:mod:`hwid.diagnose.experiments`), journalled so a rerun reuses them;
2. simulate the model on them; estimate the noise floor from repeats and test whether the gap is
   more than noise (:mod:`hwid.diagnose.gap`);
3. fit every catalogue effect (:mod:`hwid.diagnose.effects`) on the fit experiments and score it on
   the validation experiments (:mod:`hwid.diagnose.rank`); rank; verdict (:mod:`hwid.diagnose.verdict`);
4. say where the gap lies: per experiment, per region, frequencies, trend;
5. write ``OUT/diagnosis.h5`` and the JSON summary (:class:`DiagnosisResult`).

The package is also callable: ``hwid.diagnose(config, model, out_dir=...)`` is
:func:`hwid.api.diagnose` (:mod:`hwid.apinames`).
"""
from hwid.apinames import callable_as
from hwid.diagnose.effects import BLOCK, CATALOGUE
from hwid.diagnose.result import DiagnosisResult
from hwid.diagnose.conclude import ID_MIN_RATIO
from hwid.diagnose.run import diagnose
from hwid.diagnose.sim_side import load_model

__all__ = ["diagnose", "DiagnosisResult", "load_model", "CATALOGUE", "BLOCK", "ID_MIN_RATIO"]

callable_as(__name__, "diagnose")
