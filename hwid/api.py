"""The Python API: measured data in, an identified model out, compared and diagnosed.

A thin layer over the library that the CLI uses as well, so a script gets the same answers as
``hwid run``, ``hwid compare`` and ``hwid diagnose``:

* :class:`Data` holds one or several experiments (input ``u``, output ``y``, sample time ``dt``) as
  hwid's :class:`hwid.plant.Record`; :meth:`Data.from_file` reads a log with the recorded plant's own
  reader (:func:`hwid.recorded.load_records`);
* :func:`identify` runs the one identification path (:func:`hwid.identify.path.identify`) on them as
  a recorded plant: the whole model (eqs. 3a-c: F, G, h, plus the actuator where the data show one)
  fitted by output error, with 95 % intervals and its adequacy against the data's noise floor;
* :class:`Model` simulates (``y`` of eqs. 3a-c, from rest), saves to and loads from a run directory;
* :func:`compare` is ``hwid compare`` (fit percent, RMS over the noise floor, residual tests);
* :func:`diagnose` is ``hwid diagnose``.

Every config is built in memory by :mod:`hwid.config`, so the options are the config's keys and are
checked as a config's are (a bad one raises :class:`hwid.HwidError` with one line).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from hwid import HwidError

__all__ = ["Data", "Model", "identify", "compare", "diagnose"]

#: the options of :func:`identify`, each with the config key it sets
IDENTIFY_OPTIONS = {
    "max_degree": ("whole", "max_degree"),
    "max_order": ("whole", "max_order"),
    "delay": ("whole", "delay"),
    "input_type": ("whole", "input_type"),
}
#: the options of :meth:`Data.from_file` that go to the file's entry in ``plant.experiments``
FILE_OPTIONS = ("key", "decimal", "separator", "start", "stop", "role", "exclude")


def _quiet(*_args, **_kwargs) -> None:
    """An ``echo`` that says nothing (the API returns what the CLI prints)."""


def _channel(spec) -> dict:
    """A channel's config entry from a column (name or index) or a mapping with ``column``,
    ``scale``, ``offset``."""
    if isinstance(spec, dict):
        return {k: (float(v) if k != "column" else v) for k, v in spec.items()}
    return {"column": spec}


def _plant_config(name: str, dt: float, experiments: list[dict], identification: dict | None = None,
                  output_resolution: float | None = None, source_path: str = "<data>"):
    """A recorded plant's config (:class:`hwid.config.Config`) built in memory and validated."""
    from hwid import config
    plant: dict[str, Any] = {"kind": "recorded", "experiments": experiments}
    if output_resolution is not None:
        plant["output_resolution"] = float(output_resolution)
    data: dict[str, Any] = {"name": name, "sampling": {"dt": float(dt)}, "plant": plant}
    if identification:
        data["identification"] = identification
    return config.parse(data, source_text=repr(data), source_path=source_path)


def _vectors(x, what: str) -> list[np.ndarray]:
    """``x`` as a list of 1-D float arrays: one array, or a list of them (one per experiment)."""
    if isinstance(x, (list, tuple)) and x and np.ndim(x[0]) >= 1:
        out = [np.asarray(a, float).ravel() for a in x]
    else:
        out = [np.asarray(x, float).ravel()]
    if any(a.size == 0 for a in out):
        raise HwidError(f"Data: {what} holds an empty experiment")
    return out


class Data:
    """One or several experiments: the input ``u`` sent and the output ``y`` measured, every
    ``dt`` seconds (like MATLAB's ``iddata``).

    Parameters
    ----------
    u, y : array_like, or a list of array_like
        The input and the measured output; a list of arrays for several experiments (each pair of
        equal length). Samples without both signals (NaN) at the ends are not accepted here: cut
        them, or read the file with :meth:`from_file`, which cleans them as the recorded plant does.
    dt : float
        The sample time in seconds.
    names : sequence of str, optional
        The experiments' names (default ``exp1``, ``exp2``, ...).

    Attributes
    ----------
    records : tuple of hwid.plant.Record
        The experiments as hwid's records, with the levels and periodic stretches of their input
        found as a recorded file's are (:func:`hwid.recorded.segment_attrs`).

    Examples
    --------
    >>> import numpy as np, hwid
    >>> data = hwid.Data(np.sin(np.arange(200) * 0.1), np.zeros(200), dt=0.05)
    >>> len(data.records), data.records[0].name, data.dt
    (1, 'exp1', 0.05)
    """

    __slots__ = ("_records", "_dt", "_config")

    def __init__(self, u, y, dt: float, names: Sequence[str] | None = None):
        from hwid.plant import Record
        from hwid.recorded import segment_attrs
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise HwidError(f"Data: dt must be a positive number of seconds, not {dt}")
        us, ys = _vectors(u, "u"), _vectors(y, "y")
        if len(us) != len(ys):
            raise HwidError(f"Data: {len(us)} input(s) but {len(ys)} output(s)")
        names = list(names) if names is not None else [f"exp{k + 1}" for k in range(len(us))]
        if len(names) != len(us) or len(set(names)) != len(names):
            raise HwidError(f"Data: give one distinct name per experiment ({len(us)}), not {names}")
        records = []
        for name, uk, yk in zip(names, us, ys):
            if uk.size != yk.size:
                raise HwidError(f"Data: experiment {name}: u has {uk.size} samples, y {yk.size}")
            if not (np.all(np.isfinite(uk)) and np.all(np.isfinite(yk))):
                raise HwidError(f"Data: experiment {name} holds NaN or inf samples")
            records.append(Record(str(name), dt, uk, yk, attrs=segment_attrs(uk, dt)))
        self._set(tuple(records), dt, None)

    def _set(self, records: tuple, dt: float, cfg) -> None:
        object.__setattr__(self, "_records", records)
        object.__setattr__(self, "_dt", dt)
        object.__setattr__(self, "_config", cfg)

    def __setattr__(self, name, value):
        raise AttributeError("hwid.Data is immutable")

    @classmethod
    def from_records(cls, records, config=None) -> "Data":
        """Data holding ``records`` (:class:`hwid.plant.Record`, on one ``dt``) as they are."""
        records = tuple(records)
        if not records:
            raise HwidError("Data: no records")
        dts = {float(r.dt) for r in records}
        if len(dts) != 1:
            raise HwidError(f"Data: the records are on different sample times {sorted(dts)}")
        data = cls.__new__(cls)
        data._set(records, dts.pop(), config)
        return data

    @classmethod
    def from_file(cls, path, input, output, time=None, dt: float | None = None,
                  output_resolution: float | None = None, **options) -> "Data":
        """The log at ``path`` read, cleaned and put on the ``dt`` grid by the recorded plant's own
        reader (:func:`hwid.recorded.load_records`): a CSV, HDF5, NPZ or JSON file.

        Parameters
        ----------
        path : path
            The file.
        input, output : str, int or dict
            The column (name or 0-based index) of u and of y, or a mapping with ``column``,
            ``scale`` and ``offset`` (``value = scale * raw + offset``).
        time : str or int, optional
            The time column (seconds, or ISO 8601 timestamps); left out, the rows are ``dt`` apart.
        dt : float, optional
            The grid's sample time; left out, the median step of the time column (to 12 significant
            digits).
        output_resolution : float, optional
            The output's quantum (detected from the data when left out).
        **options
            The file entry's other keys: ``key``, ``decimal``, ``separator``, ``start``, ``stop``,
            ``role``, ``exclude`` (see the config reference).

        Returns
        -------
        Data
            One record per stretch of the file (a gap splits it), each with its provenance.

        Examples
        --------
        A CSV log with a time column in seconds; a pause of the logger (a gap longer than three
        sample times) splits it in two records:

        >>> import tempfile, pathlib, numpy as np, hwid
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> t = np.r_[np.arange(100), np.arange(200, 300)] * 0.01
        >>> rows = "\\n".join(f"{a:.2f},{np.sin(a):.6f},{np.cos(a):.6f}" for a in t)
        >>> _ = (folder / "log.csv").write_text("t,cmd,pos\\n" + rows)
        >>> data = hwid.Data.from_file(folder / "log.csv", input="cmd", output="pos", time="t")
        >>> data.dt, [r.name for r in data.records], [r.u.size for r in data.records]
        (0.01, ['log_part1', 'log_part2'], [100, 100])
        """
        unknown = sorted(set(options) - set(FILE_OPTIONS))
        if unknown:
            raise HwidError(f"Data.from_file: unknown option(s) {', '.join(unknown)} "
                            f"(valid: {', '.join(FILE_OPTIONS)})")
        path = Path(path).resolve()
        entry: dict[str, Any] = {"file": str(path), "input": _channel(input), "output": _channel(output),
                                 **{k: v for k, v in options.items() if v is not None}}
        if time is not None:
            entry["time"] = {"column": time}
        if dt is None:
            dt = _median_step(path, time, options.get("key"), options.get("decimal", "."), options.get("separator"))
        cfg = _plant_config(path.stem.replace(" ", "_") or "data", dt, [entry], output_resolution=output_resolution,
                            source_path=str(path))
        from hwid.recorded import load_records
        return cls.from_records(load_records(cfg), cfg)

    @property
    def records(self) -> tuple:
        """The experiments as :class:`hwid.plant.Record` (what every command works on)."""
        return self._records

    @property
    def dt(self) -> float:
        """The sample time in seconds."""
        return self._dt

    @property
    def u(self) -> list[np.ndarray]:
        """The inputs, one array per experiment."""
        return [r.u for r in self._records]

    @property
    def y(self) -> list[np.ndarray]:
        """The outputs, one array per experiment."""
        return [r.y for r in self._records]

    def __len__(self) -> int:
        return len(self._records)

    def __repr__(self) -> str:
        sizes = ", ".join(f"{r.name}: {r.u.size}" for r in self._records)
        return f"hwid.Data(dt={self._dt:g}, samples {{{sizes}}})"


def _median_step(path: Path, time, key, decimal: str, separator) -> float:
    """The median step in seconds of the time column ``time`` of the file (its own reader)."""
    if time is None:
        raise HwidError(f"Data.from_file: {path}: give dt, or the time column to take it from")
    from hwid.recorded import read_columns
    (t,), _ = read_columns(path, [time], key, decimal, separator)
    if np.issubdtype(t.dtype, np.datetime64):
        t = t[~np.isnat(t)].astype("datetime64[ns]").astype(np.int64) * 1e-9
    step = np.diff(t[np.isfinite(t)])
    step = step[step > 0]
    if not step.size:
        raise HwidError(f"Data.from_file: {path}: the time column '{time}' does not increase; give dt")
    # to 12 significant digits: a column of decimal text ("0.020000") gives steps off by 1e-17
    return float(f"{np.median(step):.12g}")


def _as_data(data) -> Data:
    if isinstance(data, Data):
        return data
    raise HwidError(f"expected hwid.Data, not {type(data).__name__} (wrap arrays as hwid.Data(u, y, dt))")


@dataclass(frozen=True)
class Model:
    """An identified (or loaded) Hammerstein-Wiener model, eqs. (3a-c), with how it was reached.

    Attributes
    ----------
    model : hwid.model.HWModel
        F, G (with its delay), h and the actuator ahead of F where one was fitted; normalised as in
        eqs. (4a-c) when identified.
    route : str
        ``"whole"`` (the whole fit), ``"stages"`` (stage 1 and 2), ``"loaded"`` (from a plant YAML).
    why : str
        One sentence on the route.
    adequacy : hwid.adequacy.Adequacy or None
        The model's residual against the data's noise floor (``verdict``: ``adequate`` or
        ``misfit``); None for a model read from a YAML.
    identification : hwid.identify.path.Identification or None
        The whole result of the identification path (intervals in ``identification.whole.ci``).
    """

    model: Any
    route: str = "loaded"
    why: str = ""
    adequacy: Any = None
    identification: Any = field(default=None, repr=False, compare=False)
    source: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def intervals(self) -> dict:
        """The 95 % intervals of F's and h's parameters (``d_plus``, ``d_minus``, ``slope_down``,
        ``h_coefficients``): the whole fit's for the route ``whole``, stage 1's (Section 4) for the
        route ``stages``; empty for a loaded model. A parameter the data cannot determine has no
        entry or None; so has h_bar's constant (``h_coefficients[0]``), fixed by h(0) = 0."""
        ident = self.identification
        source = None
        if ident is not None and ident.route == "whole" and ident.whole is not None:
            source = ident.whole.ci
        elif ident is not None and ident.route == "stages" and ident.nonlinear is not None:
            source = ident.nonlinear.ci
        if source is None:
            return {}

        def plain(v):
            return None if v is None else tuple(float(x) for x in v)
        return {k: [plain(p) for p in v] if k == "h_coefficients" else plain(v) for k, v in source.items()
                if k in ("d_plus", "d_minus", "slope_down", "h_coefficients")}

    def simulate(self, u, dt: float) -> np.ndarray:
        """The model's output ``y = h(G * F[u])`` (eqs. 3a-c, without noise) on the input ``u``
        sampled every ``dt`` seconds, from rest at ``u[0]``: the gear at its default start, G at
        the equilibrium of F's first output, the actuator (where there is one) at ``u[0]``.

        Examples
        --------
        >>> import numpy as np, hwid
        >>> from hwid.model import HWModel, InputNonlinearity
        >>> from hwid.blocks.linear import LinearBlock
        >>> from hwid.blocks.static import PolynomialH
        >>> truth = hwid.Model(HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.2, -0.2),
        ...                            LinearBlock((1.0,), (0.3, 1.0)), PolynomialH((0.0, 1.0))))
        >>> y = truth.simulate(np.r_[np.zeros(50), np.ones(500)], dt=0.01)
        >>> round(float(y[-1]), 3)       # h(G(0) (1 - d+)) = 0.8 once settled
        0.8
        """
        u = np.ascontiguousarray(u, dtype=float).ravel()
        return np.asarray(self.model.simulate(u, float(dt)).x, float)

    def to_dict(self) -> dict:
        """Plain data for JSON: the model's blocks, the route and why, the adequacy, the intervals."""
        ident = self.identification
        d = ident.to_dict() if ident is not None else {"route": self.route, "why": self.why,
                                                       "model": self.model.to_dict(),
                                                       "adequacy": None if self.adequacy is None
                                                       else self.adequacy.to_dict()}
        whole = getattr(ident, "whole", None)
        d["whole"] = None if whole is None else whole.to_dict()
        return d

    def save(self, path) -> Path:
        """Write the model to the run directory ``path`` (created), as ``hwid run`` does: the whole
        fit's ``whole.h5`` (:func:`hwid.results.write_whole`) or the stages' ``nonlinear.h5`` and
        ``linear.h5``, and ``identification.json``. The directory is a MODEL for :meth:`load`,
        ``hwid compare`` and ``hwid diagnose --model``. Returns ``path``."""
        from hwid.results import write_json, write_linear, write_nonlinear, write_whole
        from hwid.rundir import IDENTIFICATION_JSON, LINEAR, NONLINEAR, WHOLE
        ident = self.identification
        if ident is None:
            raise HwidError("Model.save: only an identified model is saved as a run directory "
                            "(a loaded one already has its file)")
        out = Path(path)
        out.mkdir(parents=True, exist_ok=True)
        cfg = self.source.get("config")
        if ident.route == "whole":
            write_whole(out / WHOLE, cfg, ident.whole, "model")
        elif ident.route == "stages":
            write_nonlinear(out / NONLINEAR, cfg, ident.nonlinear, ident.nonlinear_records)
            write_linear(out / LINEAR, cfg, ident.linear, ident.linear_records)
            if ident.whole is not None:
                write_whole(out / WHOLE, cfg, ident.whole, "beside")
        else:
            raise HwidError(f"Model.save: a model of route '{ident.route}' has no model to save")
        write_json(out / IDENTIFICATION_JSON, ident.to_dict())
        return out

    @classmethod
    def load(cls, path) -> "Model":
        """The model of a run directory (``hwid run`` or :meth:`save`) or of a plant YAML (``kind:
        hammerstein_wiener``), read as ``hwid compare`` reads its MODEL
        (:func:`hwid.diagnose.sim_side.load_model`); a run directory's adequacy comes back from its
        ``identification.json``.

        Examples
        --------
        >>> import tempfile, pathlib, hwid
        >>> plant = pathlib.Path(tempfile.mkdtemp()) / "plant.yaml"
        >>> _ = plant.write_text('''
        ... kind: hammerstein_wiener
        ... input_nonlinearity: {type: backlash, slope_up: 1.0, slope_down: 1.0, d_plus: 0.5, d_minus: -0.5}
        ... linear: {num: [2.0], den: [1.0, 1.0]}
        ... output_nonlinearity: {polynomial: [0, 1.0]}
        ... ''')
        >>> model = hwid.Model.load(plant)
        >>> model.route, float(model.simulate([0.0] * 10 + [1.5] * 2000, dt=0.01)[-1].round(4))
        ('loaded', 2.0)
        """
        from hwid.diagnose.sim_side import load_model
        model, info = load_model(str(path), echo=_quiet)
        route, why, adequacy = "loaded", f"read from {path}", None
        summary = Path(path) / "identification.json"
        if summary.is_file():
            import json
            d = json.loads(summary.read_text(encoding="utf-8"))
            route, why = d.get("route", route), d.get("why", why)
            from hwid.adequacy import Adequacy
            adequacy = Adequacy.from_dict(d.get("adequacy"))
        return cls(model, route, why, adequacy, None, {"info": info})


def _as_model(model):
    """The :class:`hwid.model.HWModel` of a :class:`Model`, an ``HWModel``, or a path to load."""
    from hwid.model import HWModel
    if isinstance(model, Model):
        return model.model
    if isinstance(model, HWModel):
        return model
    if isinstance(model, (str, Path)):
        return Model.load(model).model
    raise HwidError(f"expected a hwid.Model, a hwid.model.HWModel or a path, not {type(model).__name__}")


def identify(data, *, echo=None, **options) -> Model:
    """The model of ``data`` by the one identification path, as ``hwid run`` finds it on a recorded
    plant (:func:`hwid.identify.path.identify`): the records split into a fit part and a held-out
    part, stage 1 from their held levels (Section 4) starting the borders, then the whole model
    (eqs. 3a-c) fitted by output error with G's delay, the input's slew rate and clip where the
    criterion prefers them, and its adequacy against the data's own noise floor.

    Parameters
    ----------
    data : Data, or a config (path or :class:`hwid.config.Config`)
        The experiments; a config runs its plant as ``hwid run`` does (simulated, external or
        recorded).
    echo : callable, optional
        Called with each line ``hwid run`` prints (default: silent).
    **options
        ``max_degree`` (of h, 1-9), ``max_order`` (of G, 1-3), ``delay`` (bool: fit a pure delay
        of G), ``input_type`` (``auto``, ``backlash``, ``backlash_inverse``): the keys of
        ``identification.whole`` (and ``input_type`` of ``identification.nonlinear``).

    Returns
    -------
    Model
        With ``adequacy`` and the 95 % intervals in ``intervals``.

    Examples
    --------
    A known Backlash (play ``d+ = 0.3``, ``d- = -0.3``), a first-order G and a quadratic h,
    driven by 30 held random levels (3000 samples) with output noise 0.01:

    >>> import numpy as np, hwid
    >>> from hwid.model import HWModel, InputNonlinearity
    >>> from hwid.blocks.linear import LinearBlock
    >>> from hwid.blocks.static import PolynomialH
    >>> truth = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.3, -0.3),
    ...                 LinearBlock((1.0,), (0.2, 1.0)), PolynomialH((0.0, 1.0, 0.4)))
    >>> rng = np.random.default_rng(1)
    >>> u = np.repeat(rng.uniform(-1.5, 1.5, 30), 100)
    >>> y = truth.simulate(u, 0.02).x + 0.01 * rng.standard_normal(u.size)
    >>> model = hwid.identify(hwid.Data(u, y, dt=0.02), max_order=1, max_degree=3,
    ...                       input_type="backlash")
    >>> f = model.model.input
    >>> f.type, round(f.d_plus, 2), round(f.d_minus, 2), round(f.slope_down, 2)
    ('backlash', 0.3, -0.3, 1.0)
    >>> [round(c, 2) for c in model.model.output.coefficients]     # h_bar(w) = w + 0.4 w^2
    [0.0, 1.0, 0.4]
    >>> lo, hi = model.intervals["d_plus"]                          # its 95 % interval holds the truth
    >>> bool(lo <= 0.3 <= hi)
    True
    >>> model.adequacy.verdict                          # its residual is the noise: 0.01
    'adequate'

    Saved as a run directory and read back, it simulates the same output:

    >>> import tempfile
    >>> folder = model.save(tempfile.mkdtemp())
    >>> bool(np.array_equal(hwid.Model.load(folder).simulate(u, 0.02), model.simulate(u, 0.02)))
    True
    """
    from hwid.identify.path import identify as identify_path
    echo = echo or _quiet
    if not isinstance(data, Data):
        return _identify_config(data, echo, options)
    unknown = sorted(set(options) - set(IDENTIFY_OPTIONS))
    if unknown:
        raise HwidError(f"identify: unknown option(s) {', '.join(unknown)} (valid: {', '.join(IDENTIFY_OPTIONS)})")
    cfg = _data_config(data, options)
    ident = identify_path(cfg, records=list(data.records), echo=echo)
    return Model(ident.model, ident.route, ident.why, ident.adequacy, ident, {"config": cfg})


def _data_config(data: Data, options: dict):
    """The recorded plant's config for ``data``: the file's entry where it was read from one, else
    a placeholder entry (its records are handed to the path as they are), with ``options``."""
    ident: dict[str, dict] = {}
    for name, value in options.items():
        section, key = IDENTIFY_OPTIONS[name]
        ident.setdefault(section, {})[key] = value
    if "input_type" in options:
        ident.setdefault("nonlinear", {})["input_type"] = options["input_type"]
    base = data._config
    if base is not None:
        return _plant_config(base.name, base.sampling.dt,
                             [e.model_dump(exclude_none=True) for e in base.plant.experiments], ident,
                             base.plant.output_resolution, base.source_path)
    placeholder = [{"file": "arrays.npz", "input": {"column": "u"}, "output": {"column": "y"}}]
    return _plant_config("data", data.dt, placeholder, ident)


def _identify_config(source, echo, options: dict) -> Model:
    """:func:`identify` on a config (a path or a loaded one): its plant, as ``hwid run`` identifies it."""
    from hwid import config
    from hwid.identify.path import identify as identify_path
    if options:
        raise HwidError("identify: options go in the config's identification section when a config is given")
    cfg = source if isinstance(source, config.Config) else config.load(source)
    ident = identify_path(cfg, echo=echo)
    return Model(ident.model, ident.route, ident.why, ident.adequacy, ident, {"config": cfg})


def compare(model, data, noise_floor: float | None = None) -> dict:
    """``hwid compare``: the model's free run on each experiment of ``data``, from an initial state
    estimated from that experiment, against its measured output (:func:`hwid.compare.compare_records`).

    Parameters
    ----------
    model : Model, hwid.model.HWModel or path
        The model (a path: a run directory or a plant YAML).
    data : Data
    noise_floor : float, optional
        The output noise's standard deviation where it is known; left out, estimated from the data.

    Returns
    -------
    dict
        The JSON of ``hwid compare``: ``fit_percent``, ``rms``, ``noise_floor``, ``rms_over_floor``,
        ``experiments``, ``residual``, ``model``, ``adequacy``, ``figures`` (empty: no figures are
        drawn here).

    Examples
    --------
    >>> import numpy as np, hwid
    >>> from hwid.model import HWModel, InputNonlinearity
    >>> from hwid.blocks.linear import LinearBlock
    >>> from hwid.blocks.static import PolynomialH
    >>> truth = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.3, -0.3),
    ...                 LinearBlock((1.0,), (0.2, 1.0)), PolynomialH((0.0, 1.0, 0.4)))
    >>> rng = np.random.default_rng(2)
    >>> u = np.repeat(rng.uniform(-1.5, 1.5, 20), 100)
    >>> y = truth.simulate(u, 0.02).x + 0.01 * rng.standard_normal(u.size)
    >>> result = hwid.compare(truth, hwid.Data(u, y, dt=0.02))
    >>> round(result["rms"], 3), result["adequacy"]["verdict"]
    (0.01, 'adequate')
    """
    from hwid.compare import compare_records
    hw = _as_model(model)
    info = model.source.get("info", {}) if isinstance(model, Model) else {}
    info = {k: v for k, v in info.items() if k != "records"}
    result, _ = compare_records(hw, list(_as_data(data).records), noise_floor, info)
    return result.to_dict()


def diagnose(config, model=None, out_dir=None, effects: Sequence[str] | None = None, echo=None) -> dict:
    """``hwid diagnose``: where and why the plant of ``config`` and a model part
    (:func:`hwid.diagnose.diagnose`); writes ``out_dir/diagnosis.h5`` and ``diagnosis.json``.

    Parameters
    ----------
    config : path or hwid.config.Config
        The plant: external (a rig), simulated, or recorded logs.
    model : Model, path or None
        The sim side; None identifies it from the plant first. A :class:`Model` is saved to
        ``out_dir/model`` first.
    out_dir : path
        Where the diagnosis's files go (required).
    effects : sequence of str, optional
        The catalogue's effects to try (default: all).
    echo : callable, optional
        Called with each line ``hwid diagnose`` prints (default: silent).

    Returns
    -------
    dict
        The diagnosis JSON.
    """
    from hwid import config as config_mod
    from hwid.diagnose import diagnose as diagnose_run
    if out_dir is None:
        raise HwidError("diagnose: give out_dir, where the diagnosis's files go")
    out = Path(out_dir)
    cfg = config if isinstance(config, config_mod.Config) else config_mod.load(config)
    if isinstance(model, Model):
        if model.identification is not None:
            model = str(model.save(out / "model"))
        else:
            model = (model.source.get("info") or {}).get("path")
            if model is None:
                raise HwidError("diagnose: this model has no run directory or YAML to give the diagnosis")
    elif model is not None:
        model = str(model)
    return diagnose_run(cfg, out, model=model, effects=effects, echo=echo or _quiet)
