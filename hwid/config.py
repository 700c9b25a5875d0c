"""The YAML schema: the only place that knows the config's key names and their checks.

``load(path)`` reads YAML with the safe loader, validates every key (unknown keys are rejected with
the nearest valid name), checks the physics (stable G with G(0) != 0, slopes > 0, d_plus > d_minus,
borders that do not cross in the working range, levels and frequencies that make sense for dt)
and returns a frozen :class:`Config`. Every failure raises :class:`ConfigError` whose message is one
line: ``FILE: key.path: reason``. Every key is documented in ``docs/reference/config.md``, generated
from the descriptions here.
"""
from __future__ import annotations

import contextlib
import difflib
import hashlib
import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from hwid import HwidError
from hwid.config_effects import EFFECT_MODELS, EffectCfg, refuse_drift

Finite = Annotated[float, Field(allow_inf_nan=False)]
Pos = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class ConfigError(HwidError):
    """A config that cannot be used; the message is one line naming file, key path and reason."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class Sampling(_Strict):
    dt: Pos = Field(description="Sample time in seconds: the grid every experiment (simulated or recorded) is on.")


class InputNonlinearityCfg(_Strict):
    type: Literal["backlash", "backlash_inverse"] = Field(
        description="F of eq. (3a): a Backlash (eq. 1) or a Backlash-Inverse (eq. 2).")
    slope_up: Pos = Field(description="S^a, the slope of the ascending border.")
    slope_down: Pos = Field(description="S^d, the slope of the descending border.")
    d_plus: Finite = Field(description="d^+, where the ascending border crosses zero; must exceed d_minus.")
    d_minus: Finite = Field(description="d^-, where the descending border crosses zero.")
    initial_state: Optional[Finite] = Field(
        default=None, description="F's output before the first sample (null: 0 clipped into the band).")

    @model_validator(mode="after")
    def _gap(self):
        if not self.d_plus > self.d_minus:
            raise ValueError(f"d_plus ({self.d_plus}) must be greater than d_minus ({self.d_minus})")
        return self


class LinearCfg(_Strict):
    num: list[Finite] = Field(min_length=1, description="Numerator of G(s), descending powers of s.")
    den: list[Finite] = Field(
        min_length=1, description="Denominator of G(s), descending powers of s; G must be proper, "
                                  "asymptotically stable, with G(0) != 0.")
    delay: NonNeg = Field(default=0.0, description="Pure delay of G in seconds (exact for the sampled input, "
                                                   "fractional samples included).")

    @model_validator(mode="after")
    def _stable(self):
        num = np.trim_zeros(np.asarray(self.num, float), "f")
        den = np.trim_zeros(np.asarray(self.den, float), "f")
        if den.size == 0:
            raise ValueError("den is all zeros")
        if num.size == 0:
            raise ValueError("num is all zeros: G(s) = 0")
        if num.size > den.size:
            raise ValueError("G(s) is improper (num has a higher degree than den)")
        if den.size > 1:
            poles = np.roots(den)
            if np.any(poles.real >= 0):
                worst = poles[np.argmax(poles.real)]
                raise ValueError(f"G(s) is not asymptotically stable (pole at {worst:.4g})")
        if den[-1] == 0 or num[-1] == 0:
            raise ValueError("G(0) must be nonzero and finite (the paper normalises G by G(0), eq. 4b)")
        return self


class PiecewisePiece(_Strict):
    upper: Optional[Finite] = Field(default=None, description="Right end of this piece's range of w "
                                                              "(left out on the last piece).")
    polynomial: list[Finite] = Field(min_length=1, description="The piece's coefficients, ascending powers of w.")


class OutputNonlinearityCfg(_Strict):
    polynomial: Optional[list[Finite]] = Field(
        default=None, min_length=1, description="h(w) = sum c_i w^i, ascending powers; c_0 must be 0 "
                                                "(h^-1(0) = 0). Give this or pieces.")
    pieces: Optional[list[PiecewisePiece]] = Field(
        default=None, min_length=1, description="A piecewise polynomial h: each piece applies up to its upper. "
                                                "Give this or polynomial.")

    @model_validator(mode="after")
    def _one_form(self):
        if (self.polynomial is None) == (self.pieces is None):
            raise ValueError("give exactly one of 'polynomial' or 'pieces'")
        if self.polynomial is not None:
            if self.polynomial[0] != 0.0:
                raise ValueError("h(0) must be 0 (the paper assumes h^-1(0) = 0): polynomial[0] must be 0")
            if not any(c != 0 for c in self.polynomial):
                raise ValueError("polynomial is identically zero")
        else:
            ups = [p.upper for p in self.pieces[:-1]]
            if any(u is None for u in ups):
                raise ValueError("every piece but the last needs 'upper'")
            if self.pieces[-1].upper is not None:
                raise ValueError("the last piece extends to +inf: leave out its 'upper'")
            if any(b <= a for a, b in zip(ups, ups[1:])):
                raise ValueError("piece 'upper' bounds must increase")
        return self


class NoiseCfg(_Strict):
    std: NonNeg = Field(default=0.0, description="Standard deviation of the output noise xi(t) of eq. (3c).")
    ar: Annotated[float, Field(ge=0.0, lt=1.0)] = Field(
        default=0.0, description="AR(1) pole of coloured noise (0: white); std stays the marginal standard deviation.")


class ChannelCfg(_Strict):
    """A recorded signal: a column (name, or 0-based index), and ``value = scale * raw + offset``."""

    column: Union[Annotated[int, Field(ge=0)], Annotated[str, Field(min_length=1)]] = Field(
        description="The column: its name (CSV header, HDF5 dataset, NPZ array) or its 0-based index.")
    scale: Finite = Field(default=1.0, description="value = scale * raw + offset; must not be 0.")
    offset: Finite = Field(default=0.0, description="value = scale * raw + offset.")

    @model_validator(mode="after")
    def _scale(self):
        if self.scale == 0:
            raise ValueError("scale must not be 0 (value = scale * raw + offset)")
        return self


class TimeCfg(_Strict):
    """The time column: seconds, or ISO 8601 timestamps."""

    column: Union[Annotated[int, Field(ge=0)], Annotated[str, Field(min_length=1)]] = Field(
        description="The time column (name or 0-based index): seconds, or ISO 8601 timestamps.")


class RecordedExperimentCfg(_Strict):
    """One recorded file (CSV, HDF5, NPZ or JSON) and which of its columns are u and y."""

    file: Annotated[str, Field(min_length=1)] = Field(
        description="The log: .csv/.tsv/.txt, .h5/.hdf5, .npz or .json; relative to the config file's folder.")
    key: Optional[Annotated[str, Field(min_length=1)]] = Field(
        default=None, description="JSON: the key of the table (default data, else the whole document): a 2-D array "
                                  "(columns by index), a mapping of named columns or a list of rows by name; "
                                  "HDF5: the group holding the columns.")
    decimal: Literal[".", ","] = Field(
        default=".", description="CSV: the decimal mark of the numbers, '.' or ',' (a log written with comma "
                                 "decimals, 1,25).")
    separator: Optional[Literal["comma", "semicolon", "tab", "pipe", "space"]] = Field(
        default=None, description="CSV: the column separator by name; left out, it is sniffed from the file's first "
                                  "lines (never the comma when decimal is ',').")
    time: Optional[TimeCfg] = Field(
        default=None, description="The time column; left out, the rows are taken as dt apart.")
    input: ChannelCfg = Field(description="The input u: its column, scale and offset.")
    output: ChannelCfg = Field(description="The measured output y: its column, scale and offset.")
    start: Optional[NonNeg] = Field(
        default=None, description="Seconds from the record's first sample before which rows are left out.")
    stop: Optional[Pos] = Field(
        default=None, description="Seconds from the record's first sample after which rows are left out.")
    role: Literal["auto", "staircase", "sine", "validation", "other"] = Field(
        default="auto", description="What the record holds: auto finds held levels and steady periodic "
                                    "stretches; staircase only levels; sine only periodic stretches; "
                                    "validation and other are used as recorded (whole fit, compare).")
    exclude: list[Annotated[list[NonNeg], Field(min_length=2, max_length=2)]] = Field(
        default_factory=list, description="Disturbed stretches to leave out, [start, stop] in seconds from the "
                                          "record's first sample; the record is cut there, never bridged.")

    @model_validator(mode="after")
    def _csv_options(self):
        csv_like = Path(self.file).suffix.lower() in (".csv", ".tsv", ".txt")
        if not csv_like and (self.decimal != "." or self.separator is not None):
            raise ValueError("decimal and separator are for CSV files (.csv, .tsv, .txt) only")
        if self.separator == "comma" and self.decimal == ",":
            raise ValueError("separator and decimal must differ (both are ',')")
        return self

    @model_validator(mode="after")
    def _window(self):
        if self.start is not None and self.stop is not None and self.start >= self.stop:
            raise ValueError(f"start ({self.start}) must be before stop ({self.stop})")
        for a, b in self.exclude:
            if a >= b:
                raise ValueError(f"exclude: each stretch must start before it stops, not [{a}, {b}]")
        return self


class PlantCfg(_Strict):
    kind: Literal["hammerstein_wiener", "external", "recorded"] = Field(
        description="hammerstein_wiener: simulated (eqs. 3a-c); external: a rig or outside simulator called "
                    "through callable; recorded: logs a lab already has.")
    input_nonlinearity: Optional[InputNonlinearityCfg] = Field(
        default=None, description="F, the Backlash or Backlash-Inverse (hammerstein_wiener only).")
    linear: Optional[LinearCfg] = Field(default=None, description="G(s) (hammerstein_wiener only).")
    output_nonlinearity: Optional[OutputNonlinearityCfg] = Field(
        default=None, description="h (hammerstein_wiener only).")
    effects: Optional[list[EffectCfg]] = Field(
        default=None, description="hammerstein_wiener only: catalogue effects the plant carries at their blocks of "
                                  "the chain, each `{effect: NAME, PARAMETER: value, ...}` with the names hwid "
                                  "diagnose reports (drift cannot be simulated); a diagnosis's corrected.yaml "
                                  "writes them.")
    noise: NoiseCfg = Field(default=NoiseCfg(), description="The output noise xi(t) of a simulated plant.")
    callable: Optional[str] = Field(
        default=None, pattern=r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$",
        description="external only: \"package.module:function\", called as function(u, dt) -> y; hwid imports "
                    "and runs this code.")
    timeout: Optional[Pos] = Field(default=None, description="external only: seconds to wait for one call.")
    output_resolution: Optional[Pos] = Field(
        default=None, description="recorded only: the quantum of y in output units (an encoder's count); "
                                  "detected from the data when left out.")
    experiments: Optional[list[RecordedExperimentCfg]] = Field(
        default=None, min_length=1, description="recorded only: the files, one entry each.")

    _no_drift = field_validator("effects", mode="before")(refuse_drift)

    @model_validator(mode="after")
    def _kind(self):
        if self.effects is not None and self.kind != "hammerstein_wiener":
            raise ValueError("'effects' are only for kind: hammerstein_wiener")
        if self.kind == "recorded":
            if self.experiments is None:
                raise ValueError("a recorded plant needs experiments: a list of files with their input and output columns")
            extra = [k for k in ("input_nonlinearity", "linear", "output_nonlinearity", "callable")
                     if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"a recorded plant takes no {', '.join(extra)} (its data are the plant)")
            return self
        if self.experiments is not None or self.output_resolution is not None:
            raise ValueError("'experiments' and 'output_resolution' are only for kind: recorded")
        if self.kind == "hammerstein_wiener":
            missing = [k for k in ("input_nonlinearity", "linear", "output_nonlinearity") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"a hammerstein_wiener plant needs {', '.join(missing)}")
            if self.callable is not None:
                raise ValueError("'callable' is only for kind: external")
        else:
            if self.callable is None:
                raise ValueError("an external plant needs callable: \"package.module:function\"")
        return self


class StaircaseCfg(_Strict):
    levels_up: list[Finite] = Field(min_length=2, description="U_1 < ... < U_N of the ascending staircase, eq. (6).")
    levels_down: list[Finite] = Field(min_length=2, description="The descending staircase's levels, eq. (13).")
    hold: Pos = Field(description="Seconds per level; at least 20 samples.")

    @model_validator(mode="after")
    def _monotone(self):
        if any(b <= a for a, b in zip(self.levels_up, self.levels_up[1:])):
            raise ValueError("levels_up must be strictly increasing (eq. 6)")
        if any(b >= a for a, b in zip(self.levels_down, self.levels_down[1:])):
            raise ValueError("levels_down must be strictly decreasing (eq. 13)")
        return self


class SineCfg(_Strict):
    amplitude: Pos = Field(description="U of eq. (15).")
    frequencies: list[Pos] = Field(min_length=1, description="omega_i in rad/s; each below the Nyquist frequency "
                                                             "with at least 8 samples a period.")
    periods: Annotated[int, Field(ge=1)] = Field(description="N of eq. (23a): periods averaged.")
    lead_in_periods: Annotated[int, Field(ge=0)] = Field(
        default=3, description="Periods run first and discarded (G's transient).")


class ProtocolsCfg(_Strict):
    staircase: Optional[StaircaseCfg] = Field(default=None, description="Stage 1's two staircases (Section 4).")
    sine: Optional[SineCfg] = Field(default=None, description="Stage 2's sines behind the pre-compensator (Section 5).")

    @model_validator(mode="after")
    def _some(self):
        if self.staircase is None and self.sine is None:
            raise ValueError("give at least one of 'staircase' or 'sine'")
        return self


class NonlinearIdCfg(_Strict):
    """Stage 1 (hwid.identify.nonlinear).

    method: nls (joint weighted least squares, default) | paper (closed form of eqs. 11-14);
    degree: p of h, or null to select it by BIC up to max_degree;
    input_type: auto (decide Backlash / Backlash-Inverse from the data, Remark 1.4) | backlash |
      backlash_inverse (skip the decision when the type is known);
    alpha: family-wise level of the tests that find the horizontal paths j_a, j_d (per staircase);
    pool_noise: pool the output noise's long-run variance over all levels (stationary noise).
    """

    method: Literal["nls", "paper"] = Field(
        default="nls", description="nls: joint weighted least squares; paper: the closed form of eqs. (11)-(14).")
    degree: Optional[Annotated[int, Field(ge=1, le=15)]] = Field(
        default=None, description="Fix the degree p of h (null: selected from the data by BIC).")
    max_degree: Annotated[int, Field(ge=1, le=15)] = Field(default=9, description="Largest degree of h tried.")
    input_type: Literal["auto", "backlash", "backlash_inverse"] = Field(
        default="auto", description="auto decides Backlash or Backlash-Inverse from the data (Remark 1.4); "
                                    "the others skip the decision.")
    alpha: Annotated[float, Field(gt=0.0, lt=0.5)] = Field(
        default=0.01, description="Family-wise level of the tests that find the horizontal paths j_a, j_d.")
    pool_noise: bool = Field(
        default=True, description="Pool the noise's long-run variance over all levels (stationary noise).")


class LinearIdCfg(_Strict):
    method: Literal["nls", "paper"] = Field(
        default="nls", description="nls: maximum likelihood on all harmonics (eq. 20); paper: eq. (37) on one harmonic.")
    harmonic: Optional[Annotated[int, Field(ge=1)]] = Field(
        default=None, description="The harmonic method paper uses (null: the highest significant one).")
    precompensator: Literal["auto", "backlash", "border_map"] = Field(
        default="auto", description="Fig. 8's pre-compensator; auto: B_inv for a Backlash, the border map for a "
                                    "Backlash-Inverse.")
    max_order: Annotated[int, Field(ge=1, le=8)] = Field(default=4, description="Largest order of the parametric G(s).")
    fit_delay: bool = Field(default=False, description="Also fit a pure delay in the parametric G(s).")
    hold_correction: bool = Field(
        default=True, description="Divide out the zero-order hold of the sampled input (a dt/2 delay).")
    noise_model: Literal["auto", "white", "periodic"] = Field(
        default="auto", description="Harmonic standard errors from the residual variance (white) or the spread "
                                    "over periods (periodic, coloured noise); auto tests which.")


class WholeIdCfg(_Strict):
    """The whole-model output-error fit (hwid.identify.whole), run by ``hwid run`` when enabled.

    max_degree: highest degree of h_bar tried (selected by BIC); max_order: highest order of G
    tried (1-3; structures with and without a zero); delay: also fit a pure delay of G;
    input_type: auto (both types tried, BIC decides; the stages' type when they ran) | backlash |
      backlash_inverse.
    """

    enabled: bool = Field(default=False, description="hwid run also fits the whole model by output error (whole.h5).")
    max_degree: Annotated[int, Field(ge=1, le=9)] = Field(default=5, description="Highest degree of h_bar tried.")
    max_order: Annotated[int, Field(ge=1, le=3)] = Field(
        default=3, description="Highest order of G tried (real poles, pole pairs, with and without a zero); one "
                                "more pole or pair may replace a right-half-plane zero or a delay where it fits better.")
    delay: bool = Field(default=False, description="Also fit a pure delay of G.")
    input_type: Literal["auto", "backlash", "backlash_inverse"] = Field(
        default="auto", description="Type of F tried; auto: both, the criterion decides (after the stages: theirs).")


class IdentificationCfg(_Strict):
    nonlinear: NonlinearIdCfg = Field(default=NonlinearIdCfg(), description="Stage 1 (Section 4).")
    linear: LinearIdCfg = Field(default=LinearIdCfg(), description="Stage 2 (Section 5).")
    whole: WholeIdCfg = Field(default=WholeIdCfg(), description="The whole-model fit from any input.")


class Config(_Strict):
    name: Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9_.+-]+$")] = Field(
        description="The run's name; paper-section6 makes reports show the paper's own values beside.")
    seed: Annotated[int, Field(ge=0, lt=2**63)] = Field(
        default=0, description="Root of numpy's SeedSequence: every experiment's noise comes from it.")
    sampling: Sampling = Field(description="The time grid.")
    plant: PlantCfg = Field(description="What is identified: a simulated plant, an external rig, or recorded logs.")
    # a recorded plant's records are its experiments: its config may leave protocols out (the
    # default, not validated, holds neither); other plants must give them (checked in parse)
    protocols: ProtocolsCfg = Field(
        default_factory=lambda: ProtocolsCfg.model_construct(staircase=None, sine=None),
        description="The experiments run on the plant; required but for a recorded plant.")
    identification: IdentificationCfg = Field(default=IdentificationCfg(), description="The estimators' settings.")

    # set by load(): the source text and its hash (provenance); not config keys
    source_text: str = Field(default="", exclude=True, repr=False)
    source_path: str = Field(default="<config>", exclude=True, repr=False)

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.source_text.encode()).hexdigest()


# ---------------------------------------------------------------- physics checks (need the whole config)

MAX_SAMPLES = 10**8  # per experiment: 0.8 GB per stored signal


def _physics(cfg: Config) -> list[tuple[str, str]]:
    errs: list[tuple[str, str]] = []
    dt = cfg.sampling.dt
    st, sn = cfg.protocols.staircase, cfg.protocols.sine
    p = cfg.plant
    if st is not None:
        if st.hold < 20 * dt:
            errs.append(("protocols.staircase.hold", f"{st.hold} s is fewer than 20 samples of dt = {dt} s"))
        levels = st.levels_up + st.levels_down
        lo, hi = min(levels), max(levels)
        if p.kind == "hammerstein_wiener":
            f = p.input_nonlinearity
            for u in (lo, hi):
                if f.type == "backlash":
                    up, dn = f.slope_up * (u - f.d_plus), f.slope_down * (u - f.d_minus)
                    bad = up > dn
                else:
                    up, dn = u / f.slope_up + f.d_plus, u / f.slope_down + f.d_minus
                    bad = up < dn
                if bad:
                    errs.append(("plant.input_nonlinearity",
                                 f"the borders cross inside the staircase range at u = {u:g} "
                                 f"(ascending {up:.4g}, descending {dn:.4g}); narrow the levels or fix the slopes"))
                    break
        fixed = cfg.identification.nonlinear.degree
        if fixed is not None:
            for key, lv in (("levels_up", st.levels_up), ("levels_down", st.levels_down)):
                if len(lv) < fixed + 1:
                    errs.append((f"protocols.staircase.{key}",
                                 f"{len(lv)} levels cannot support degree {fixed}: eq. (11) needs at least "
                                 f"{fixed + 1} levels on the border"))
    if sn is not None:
        nyq = math.pi / dt
        for i, w in enumerate(sn.frequencies):
            if w >= nyq:
                errs.append((f"protocols.sine.frequencies[{i}]",
                             f"{w} rad/s is at or above the Nyquist frequency pi/dt = {nyq:.4g} rad/s"))
            elif 2 * math.pi / w < 8 * dt:
                errs.append((f"protocols.sine.frequencies[{i}]",
                             f"{w} rad/s leaves fewer than 8 samples per period at dt = {dt} s"))
    if p.kind == "hammerstein_wiener" and p.linear.delay > 0 and p.linear.delay > 1e6 * dt:
        errs.append(("plant.linear.delay", "delay is more than 10^6 samples"))
    # experiment lengths (samples) that fit in memory: protocols.staircase / protocols.sine
    if st is not None:
        n = (len(st.levels_up) + 2) * (st.hold / dt)
        if n > MAX_SAMPLES:
            errs.append(("protocols.staircase.hold", f"the staircase would last {n:.3g} samples of dt = {dt} s, "
                                                     f"more than the limit of {MAX_SAMPLES:.0e}"))
    if sn is not None:
        n = (sn.periods + sn.lead_in_periods) * 2 * math.pi / min(sn.frequencies) / dt
        if n > MAX_SAMPLES:
            errs.append(("protocols.sine.periods", f"the slowest sine would last {n:.3g} samples of dt = {dt} s, "
                                                   f"more than the limit of {MAX_SAMPLES:.0e}"))
    return errs


def _key_text(key: Any) -> str:
    """A key as the message shows it: as written if plain, else quoted with escapes (so that a key
    holding a newline or a control character cannot break the one-line message)."""
    text = str(key)
    return text if text and text.isprintable() and text.strip() == text else repr(text)


def _loc(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + _key_text(part)
    return out


def _valid_keys(model: type[BaseModel]) -> list[str]:
    return [k for k in model.model_fields if k not in ("source_text", "source_path")]


def _model_at(loc: tuple) -> Optional[type[BaseModel]]:
    """The pydantic model class that owns the mapping at ``loc`` (for key suggestions)."""
    model: Any = Config
    for part in loc:
        if isinstance(part, int):
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)) or part not in model.model_fields:
            return None
        ann = model.model_fields[part].annotation
        model = _unwrap(ann)
    return model if isinstance(model, type) and issubclass(model, BaseModel) else None


def _unwrap(ann):
    import typing
    for _ in range(4):
        args = typing.get_args(ann)
        origin = typing.get_origin(ann)
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            return ann
        if origin in (Union, list, Optional) or args:
            cands = [a for a in args if a is not type(None)]
            ann = next((a for a in cands if isinstance(a, type) and issubclass(a, BaseModel)), cands[0] if cands else None)
        else:
            return ann
    return ann


def _first_error(err: ValidationError) -> tuple[str, str]:
    errors = err.errors()
    e = _misspelt_instead(errors) or errors[0]
    return _describe(e)


def _misspelt_instead(errors) -> dict | None:
    """An unknown key that is a near-miss of a required key missing beside it (``dem`` for ``den``):
    the typo is the error to name, not the missing key."""
    for missing in (e for e in errors if e["type"] == "missing"):
        parent, name = tuple(missing["loc"][:-1]), str(missing["loc"][-1])
        for extra in (e for e in errors if e["type"] == "extra_forbidden"):
            if tuple(extra["loc"][:-1]) == parent and difflib.get_close_matches(str(extra["loc"][-1]), [name], n=1,
                                                                                 cutoff=0.5):
                return extra
    return None


def _untagged(loc: tuple) -> tuple[tuple, Optional[type[BaseModel]]]:
    """``loc`` without the effect's name pydantic puts after an entry of ``effects`` (its tag), and
    that effect's schema (None where there is none)."""
    for i in range(2, len(loc)):
        if loc[i - 2] == "effects" and isinstance(loc[i - 1], int) and loc[i] in EFFECT_MODELS:
            return loc[:i] + loc[i + 1:], EFFECT_MODELS[loc[i]]
    return loc, None


def _describe(e: dict) -> tuple[str, str]:
    loc = tuple(e["loc"])
    # strip pydantic's union/validator tags such as 'function-after[...]'
    loc = tuple(p for p in loc if not (isinstance(p, str) and ("[" in p and "]" in p and "function" in p)))
    loc, effect_model = _untagged(loc)
    kind = e["type"]
    if kind == "union_tag_invalid":
        tag = str((e.get("ctx") or {}).get("tag", ""))
        close = difflib.get_close_matches(tag, list(EFFECT_MODELS), n=1, cutoff=0.5)
        hint = f"did you mean '{close[0]}'? " if close else ""
        return _loc(loc), f"unknown effect {tag!r} ({hint}the effects a plant can carry: {', '.join(EFFECT_MODELS)})"
    if kind == "extra_forbidden":
        key = loc[-1]
        owner = effect_model if effect_model is not None and len(loc) >= 2 and isinstance(loc[-2], int) \
            else _model_at(loc[:-1])
        hint = ""
        if owner is not None:
            close = difflib.get_close_matches(str(key), _valid_keys(owner), n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else f" (valid keys: {', '.join(_valid_keys(owner))})"
        shown = _key_text(key)
        quoted = shown if shown != str(key) else f"'{shown}'"
        return _loc(loc), f"unknown key {quoted}{hint}"
    if kind == "missing":
        return _loc(loc), "required key is missing"
    msg = e["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    ctx = e.get("ctx") or {}
    if kind in ("finite_number",):
        msg = "must be a finite number (no NaN or inf)"
    elif kind in ("dict_type", "model_type", "model_attributes_type"):
        msg = "must be a mapping of keys"
    elif kind == "too_short":
        msg = f"must have at least {ctx.get('min_length')} item(s), got {ctx.get('actual_length')}"
    elif kind == "too_long":
        msg = f"must have at most {ctx.get('max_length')} item(s), got {ctx.get('actual_length')}"
    elif kind == "string_too_long":
        msg = f"must have at most {ctx.get('max_length')} characters"
    elif kind == "string_too_short":
        msg = "must not be empty"
    elif kind == "string_pattern_mismatch":
        msg = "may contain only letters, digits and _ . + -" if loc == ("name",) else \
              f"must look like {'package.module:function' if loc[-1:] == ('callable',) else ctx.get('pattern')}"
    elif msg.startswith("Input should be "):
        msg = "must be " + msg[len("Input should be "):]
    got = e.get("input")
    if kind in ("float_type", "int_type") and isinstance(got, str):
        with contextlib.suppress(ValueError):
            float(got)
            msg += " (a quoted number is a string in YAML)"
    if "input" in e and kind != "missing" and (kind.endswith("_type") or not isinstance(got, (dict, list))):
        shown = repr(got) if not isinstance(got, (dict, list)) else f"a {'mapping' if isinstance(got, dict) else 'list'}"
        msg += f" (got {shown if len(shown) <= 60 else shown[:57] + '...'})"
    return _loc(loc), msg


def parse(data: Any, source_text: str = "", source_path: str = "<config>") -> Config:
    """Validate a mapping (already parsed YAML); raise :class:`ConfigError` with one line."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source_path}: the config must be a YAML mapping of keys, got {type(data).__name__}")
    plant = data.get("plant")
    if "protocols" not in data and isinstance(plant, dict) and plant.get("kind") != "recorded":
        raise ConfigError(f"{source_path}: protocols: required key is missing")
    try:
        cfg = Config.model_validate({**data, "source_text": source_text, "source_path": source_path})
    except ValidationError as err:
        where, why = _first_error(err)
        raise ConfigError(f"{source_path}: {where or '(top level)'}: {why}") from None
    errs = _physics(cfg)
    if errs:
        where, why = errs[0]
        raise ConfigError(f"{source_path}: {where}: {why}")
    return cfg


class _SafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader (plain data only: no tags that build objects), made stricter:

    * a key given twice in one mapping is an error (PyYAML silently keeps the last one);
    * ``1e-3`` and ``1E6`` are numbers, as in YAML 1.2 (PyYAML's YAML 1.1 rules read them as
      strings, so ``dt: 1e-3`` would be rejected as "not a number")."""


_SafeLoader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_SafeLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+)$"""),
    list("-+0123456789"))


def _no_duplicates(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    seen: dict = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            hash(key)
        except TypeError:
            break  # let the default constructor report the unhashable key
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"key '{key}' is given twice (first on line {seen[key] + 1})", key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


_SafeLoader.add_constructor("tag:yaml.org,2002:map", _no_duplicates)


def safe_yaml(text: str):
    """Parse YAML with the safe loader (plus duplicate-key rejection); never constructs objects."""
    loader = _SafeLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def loads(text: str, source_path: str = "<config>") -> Config:
    """Parse YAML text (safe loader only) and validate it."""
    try:
        data = safe_yaml(text)
    except RecursionError:
        raise ConfigError(f"{source_path}: YAML: nested too deeply to be a config") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "YAML"
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ConfigError(f"{source_path}: {where}: malformed YAML ({problem})") from None
    return parse(data, source_text=text, source_path=source_path)


def load(path: str | Path) -> Config:
    """Read and validate a config file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: cannot read the config ({type(err).__name__})") from None
    return loads(text, source_path=str(path))


def with_overrides(cfg: Config, overrides: dict[str, Any]) -> Config:
    """A copy of ``cfg`` with dotted keys replaced (``{"plant.noise.std": 0.03}``), validated again.

    Used by ``hwid batch --sweep``; the resulting text (and hash) records the overrides.
    """
    data = yaml.safe_load(cfg.source_text) if cfg.source_text else cfg.model_dump()
    for key, value in overrides.items():
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts):
            if not isinstance(node, dict):
                where = ".".join(parts[:i]) or "(top level)"
                raise ConfigError(f"{cfg.source_path}: {key}: cannot set it, {where} is not a mapping "
                                  f"of keys (it is {type(node).__name__} {str(node)[:40]})")
            if i == len(parts) - 1:
                node[part] = value
            else:
                node = node.setdefault(part, {})
    text = yaml.safe_dump(data, sort_keys=False)
    return loads(text, source_path=f"{cfg.source_path} [{', '.join(f'{k}={v}' for k, v in overrides.items())}]")


def parse_plant(data: Any, source: str) -> PlantCfg:
    """Validate a plant mapping on its own (a ``--model`` file); raise :class:`ConfigError` with one
    line ``SOURCE: plant.KEY: reason``."""
    try:
        return PlantCfg.model_validate(data)
    except ValidationError as err:
        where, why = _first_error(err)
        raise ConfigError(f"{source}: plant.{where}: {why}") from None
