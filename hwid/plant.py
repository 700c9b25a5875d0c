"""A simulated plant and the external-rig adapter, behind one interface: ``plant.run(name, u) -> Record``.

* :class:`SimulatedPlant` runs eqs. (3a-c): ``v = F[u]`` (the gear keeps its state from one
  experiment to the next, like a rig), ``w = G * v`` from the equilibrium of the first sample,
  ``x = h(w)``, ``y = x + xi``. The noise of each experiment comes from its own ``Generator``,
  spawned from the run's ``SeedSequence`` and the experiment's name, so results do not depend on the
  order experiments are run in. White noise is drawn inside the chain's own pass
  (:func:`hwid.blocks.chain.run_chain`), bit-identical to :func:`noise` added to x afterwards.
* :class:`ExternalPlant` calls ``function(u, dt) -> y`` named by ``plant.callable`` once per
  experiment, checks what it returns, and journals every call's (u, y) to disk at once, so a rerun
  reuses recorded rig time instead of repeating it.
"""
from __future__ import annotations

import hashlib
import importlib
import inspect
import os
import threading
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional

import numpy as np

from hwid import HwidError

if TYPE_CHECKING:
    from hwid.model import HWModel


@dataclass
class Record:
    """One experiment: the input ``u`` sent to the plant and the measured output ``y``.

    ``v, w, x`` are the internal signals (ground truth, simulated plants only); ``z`` is the
    pre-compensator's input when one was used (Fig. 8)."""

    name: str
    dt: float
    u: np.ndarray
    y: np.ndarray
    v: Optional[np.ndarray] = None
    w: Optional[np.ndarray] = None
    x: Optional[np.ndarray] = None
    z: Optional[np.ndarray] = None
    attrs: dict = field(default_factory=dict)

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.u.size) * self.dt


def experiment_rng(seed_seq: np.random.SeedSequence, name: str) -> np.random.Generator:
    """A Generator for one named experiment, independent of the order experiments run in."""
    child = np.random.SeedSequence(seed_seq.entropy, spawn_key=tuple(seed_seq.spawn_key) + (zlib.crc32(name.encode()),))
    return np.random.default_rng(child)


def noise(rng: np.random.Generator, n: int, std: float, ar: float = 0.0) -> np.ndarray:
    """Zero-mean Gaussian noise with marginal standard deviation ``std``; AR(1) with pole ``ar``."""
    if std == 0.0:
        return np.zeros(n)
    e = rng.standard_normal(n)
    if ar == 0.0:
        e *= std            # in place: a long experiment's noise is not allocated twice
        return e
    from scipy import signal   # imported here: scipy.signal costs seconds at start-up
    b = [std * np.sqrt(1 - ar * ar)]
    zi = np.array([ar * std * rng.standard_normal()])  # stationary start
    return signal.lfilter(b, [1.0, -ar], e, zi=zi)[0]


class SimulatedPlant:
    """Eqs. (3a-c) with the true (un-normalised) model."""

    kind = "hammerstein_wiener"

    def __init__(self, model: HWModel, dt: float, noise_std: float = 0.0, noise_ar: float = 0.0,
                 seed: np.random.SeedSequence | int = 0, initial_state: float | None = None):
        self.model = model
        self.dt = float(dt)
        self.noise_std = float(noise_std)
        self.noise_ar = float(noise_ar)
        self.seed_seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.state = initial_state
        self.calls = 0
        self.reused = 0         # a simulation is never answered from a journal

    def run(self, name: str, u, z=None) -> Record:
        u = np.ascontiguousarray(u, dtype=float)
        rng = experiment_rng(self.seed_seq, name)
        white = self.noise_std != 0.0 and self.noise_ar == 0.0     # drawn in the chain's own pass
        sig = self.model.simulate(u, self.dt, self.state, noise_rng=rng if white else None, noise_std=self.noise_std)
        self.state = sig.gear
        v, w, x = sig.v, sig.w, sig.x
        if white:
            y = sig.y
        else:
            y = noise(rng, u.size, self.noise_std, self.noise_ar)
            y += x          # in place; the same sum as x + noise
        self.calls += 1
        if not np.all(np.isfinite(y)):
            raise HwidError(f"simulating experiment '{name}' gave NaN or inf (first at sample "
                            f"{int(np.argmin(np.isfinite(y)))}): the plant's coefficients or the protocol's "
                            f"levels are too large for floating point")
        return Record(name, self.dt, u, y, v, w, x, None if z is None else np.asarray(z, float))


def load_callable(spec: str) -> Callable:
    """Import ``package.module:function`` (only for ``plant.kind: external``) and check its signature."""
    mod_name, _, fn_name = spec.partition(":")
    try:
        mod = importlib.import_module(mod_name)
    except (Exception, SystemExit) as err:  # noqa: BLE001 - any import failure is the user's to fix
        raise HwidError(f"cannot import module '{mod_name}' ({type(err).__name__}: {err})") from None
    fn = getattr(mod, fn_name, None)
    if fn is None or not callable(fn):
        raise HwidError(f"module '{mod_name}' has no function '{fn_name}'")
    try:
        sig = inspect.signature(fn)
        sig.bind(np.zeros(1), 0.01)
    except TypeError:
        raise HwidError(f"'{spec}' must accept (u: numpy.ndarray, dt: float), "
                        f"its signature is {fn_name}{sig}") from None
    except ValueError:
        pass  # builtins without a signature: trust them
    return fn


def load_external(cfg) -> Callable:
    """The callable of an external plant config; errors name the config file and key."""
    try:
        return load_callable(cfg.plant.callable)
    except HwidError as err:
        raise HwidError(f"{cfg.source_path}: plant.callable: {err}") from None


class RigJournal:
    """Every external call's (u, y) on disk, one ``.npz`` per call, written atomically.

    A call is found again by its experiment name and the SHA-256 of its input, so a rerun of the
    same protocol reuses the recorded output instead of driving the rig again."""

    def __init__(self, directory: str | Path):
        self.dir = Path(directory)

    @staticmethod
    def key(name: str, u: np.ndarray, dt: float) -> str:
        h = hashlib.sha256(np.ascontiguousarray(u, dtype=float).tobytes() + repr(float(dt)).encode()).hexdigest()[:16]
        # only [A-Za-z0-9_.-], at most 80 characters, plus the hash: always one plain file name
        # inside the journal directory, whatever the experiment's name
        safe = "".join(c if (c.isascii() and c.isalnum()) or c in "_-." else "_" for c in name)[:80]
        return f"{safe}-{h}"

    def get(self, name: str, u: np.ndarray, dt: float) -> Optional[np.ndarray]:
        p = self.dir / (self.key(name, u, dt) + ".npz")
        if not p.exists():
            return None
        try:
            with np.load(p) as f:
                if f["u"].shape == u.shape and np.array_equal(f["u"], u):
                    y = np.asarray(f["y"], dtype=float)
                    if y.shape == u.shape and np.all(np.isfinite(y)):
                        return y.copy()
        except Exception:  # noqa: BLE001 - a broken journal entry is ignored and redone
            return None
        return None

    def put(self, name: str, u: np.ndarray, y: np.ndarray, dt: float, rejected: bool = False) -> Path:
        """Record one call; ``rejected=True`` files it under ``rejected/`` (kept, never reused)."""
        d = self.dir / "rejected" if rejected else self.dir
        d.mkdir(parents=True, exist_ok=True)
        p = d / (self.key(name, u, dt) + ".npz")
        tmp = p.with_suffix(".npz.tmp")
        with open(tmp, "wb") as fh:
            np.savez(fh, u=u, y=y, dt=dt, name=name)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
        return p


class RigError(HwidError):
    """An external plant that failed, hung or returned something unusable; names the experiment."""


class ExternalPlant:
    """A real rig or outside simulator: ``function(u, dt) -> y``, one call per experiment."""

    kind = "external"

    def __init__(self, spec: str, dt: float, timeout: float | None = None, journal: RigJournal | None = None,
                 fn: Callable | None = None):
        self.spec = spec
        self.fn = fn if fn is not None else load_callable(spec)
        self.dt = float(dt)
        self.timeout = timeout
        self.journal = journal
        self.calls = 0          # calls that reached the rig
        self.reused = 0         # calls answered from the journal

    def _call(self, name: str, u: np.ndarray):
        if self.timeout is None:
            return self.fn(u.copy(), self.dt)
        box: dict = {}

        def target():
            try:
                box["y"] = self.fn(u.copy(), self.dt)
            except BaseException as err:  # noqa: BLE001 - re-raised in the caller's thread
                box["err"] = err if isinstance(err, Exception) else RuntimeError(f"{type(err).__name__}({err})")

        th = threading.Thread(target=target, daemon=True, name=f"rig-{name}")
        th.start()
        th.join(self.timeout)
        if th.is_alive():
            raise RigError(f"external plant '{self.spec}' call for experiment '{name}' did not return "
                           f"within {self.timeout:g} s (plant.timeout)")
        if "err" in box:
            raise box["err"]
        return box.get("y")

    def run(self, name: str, u, z=None) -> Record:
        u = np.ascontiguousarray(u, dtype=float)
        y = self.journal.get(name, u, self.dt) if self.journal else None
        if y is not None:
            self.reused += 1
        else:
            try:
                y = self._call(name, u)
            except RigError:
                raise
            except (Exception, SystemExit) as err:  # noqa: BLE001 - the rig's failure, in one line
                raise RigError(f"external plant '{self.spec}' failed on experiment '{name}': "
                               f"{type(err).__name__}: {err}") from None
            self.calls += 1
            if y is None:
                raise RigError(f"external plant '{self.spec}' returned None for experiment '{name}' "
                               f"(expected an array of {u.size} samples)")
            try:
                y = np.asarray(y, dtype=float).reshape(-1)
            except Exception:  # noqa: BLE001 - anything that is not an array of numbers
                raise RigError(f"external plant '{self.spec}' returned something that is not an array of "
                               f"numbers for experiment '{name}' ({type(y).__name__})") from None
            problem = None
            if y.shape != u.shape:
                problem = f"returned {y.size} samples for experiment '{name}', expected {u.size}"
            elif not np.all(np.isfinite(y)):
                problem = (f"returned NaN or inf for experiment '{name}' "
                           f"(first at sample {int(np.argmin(np.isfinite(y)))})")
            if problem:
                kept = ""
                if self.journal:   # rig time is not thrown away: kept for inspection, never reused
                    kept = f"; the output is kept in {self.journal.put(name, u, y, self.dt, rejected=True)}"
                raise RigError(f"external plant '{self.spec}' {problem}{kept}")
            if self.journal:
                self.journal.put(name, u, y, self.dt)
        return Record(name, self.dt, u, y, z=None if z is None else np.asarray(z, float),
                      attrs={"external": self.spec})


def make_plant(cfg, seed: np.random.SeedSequence | int | None = None, journal_dir: str | Path | None = None):
    """The plant of ``cfg.plant``: simulated or external."""
    p = cfg.plant
    if p.kind == "recorded":
        raise HwidError(f"{cfg.source_path}: a recorded plant cannot run new experiments; its records are read "
                        f"with 'hwid simulate' (and compared with 'hwid compare')")
    if p.kind == "external":
        return ExternalPlant(p.callable, cfg.sampling.dt, p.timeout,
                             RigJournal(journal_dir) if journal_dir is not None else None, fn=load_external(cfg))
    from hwid.model import from_config   # the numba kernels load only for simulated plants
    seed = cfg.seed if seed is None else seed
    return SimulatedPlant(from_config(p), cfg.sampling.dt, p.noise.std, p.noise.ar, seed,
                          p.input_nonlinearity.initial_state)
