"""The joint model of all given shots: the simulator, its parameters, and the fit.

Parameters (SI units):

* shared by the shots (one sheet of ice): ``phi_y``, ``alpha_y`` (translation friction
  mu = alpha v^phi, alpha in (m/s)^-phi), ``phi_theta``, ``alpha_theta`` (rotation) --
  with several shots alpha is per shot (``alpha_y[i]``, ``alpha_theta[i]``): one sheet,
  not identical friction under every throw,
  ``a_T`` (m/s^2, the size of the transverse acceleration; its direction follows the
  spin, so shots of opposite spin curl to opposite sides);
* per shot ``i``: ``v0[i]`` (m/s), ``omega0[i]`` (rad/s, > 0 counter-clockwise), and the
  nuisance offsets of the measured frame ``x0[i]``, ``y0[i]`` (m), ``theta0[i]`` (rad)
  and ``skew[i]`` (rad; data = offset + Rot(skew) (simulated x, y), as in
  :mod:`curltrack.fit`) -- the contract's origin and axes are themselves estimates;
* the candidate's effect parameters.

The forward model is :func:`curltrack.physics.simulate`; nothing here is physics.
Residuals are divided by each row's noise and AR(1)-whitened per (shot, coordinate), so
the fit is weighted least squares under the noise model estimated from the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from ..fitting import parameters, solve, vector
from ..physics.params import SHOT_MODEL, covariance
from ..rig import default_rig
from .candidates import Candidate, effects_for
from ..series.noise import whiten
from .shots import COORDS

SHARED = ("phi_y", "alpha_y", "phi_theta", "alpha_theta", "a_T")
PER_SHOT = ("v0", "omega0", "x0", "y0", "theta0", "skew")
#: smallest spin (rad/s) of a position-only shot whose curl's end is fitted: its side is
#: the curl's, so it never reaches 0
OMEGA_MIN = 0.01

def _base(name: str) -> str:
    return name.split("[")[0]


def _shot_of(name: str):
    return int(name[name.index("[") + 1:-1]) if "[" in name else None


@dataclass
class FitOut:
    """A fitted joint model (lmfit-like: ``success``, ``message``, ``var_names``,
    ``covar``, ``bic``, ``redchi``): values, errors, chi-square, Jacobian.

    Attributes
    ----------
    values : dict
        All parameter values (free and fixed), per-shot ones as ``"v0[0]"``.
    free : list of str
        The fitted parameters, in the order of ``cov`` and ``J``.
    cov : (p, p) array
        Covariance of the free parameters (scaled by the reduced chi-square if > 1).
    chi2 : float
        Sum of squared whitened residuals.
    n : int
        Number of data points.
    r, J : arrays
        Whitened residuals (data - model) and whitened d(model)/d(free) at the fit.
    r_raw, J_raw : arrays
        The same in physical units (m, rad), unweighted.
    predictions : list of dict
        Per shot, model ``x``, ``y``, ``theta`` at the shot's rows.
    """

    values: dict
    free: list
    cov: np.ndarray
    chi2: float
    n: int
    r: np.ndarray
    J: np.ndarray
    r_raw: np.ndarray
    J_raw: np.ndarray
    predictions: list
    success: bool
    message: str

    @property
    def k(self) -> int:
        return len(self.free)

    # lmfit's names for the same things
    @property
    def var_names(self) -> list:
        return list(self.free)

    @property
    def covar(self) -> np.ndarray:
        return self.cov

    @property
    def bic(self) -> float:
        """chi-square + k ln n (the noise is known: whitened residuals)."""
        return float(self.chi2 + self.k * np.log(self.n))

    @property
    def redchi(self) -> float:
        return self.chi2 / max(self.n - self.k, 1)

    def err(self, name: str) -> float:
        i = self.free.index(name) if name in self.free else None
        return float(np.sqrt(max(self.cov[i, i], 0.0))) if i is not None else 0.0


class JointModel:
    """Baseline (+ one candidate) over all shots.

    Parameters
    ----------
    shots : list of ShotData
    baseline : {"paper", "dry"}
        ``dry`` holds ``phi_y`` and ``phi_theta`` at 0.
    cand : Candidate, optional
    rig : Rig, optional
        Supplies R and r of the rock.
    """

    def __init__(self, shots, baseline: str = "paper", cand: Candidate | None = None, rig=None,
                 phi_per_shot: bool = False):
        from ..physics import ShotModel, simulate

        self._ShotModel, self._simulate = ShotModel, simulate
        #: candidate values held fixed (a scan location, a pick's shot index)
        self.cand_fixed: dict | None = None
        rig = rig or default_rig()
        self.rig = rig
        #: each shot its own friction exponents (``phi_y[i]``, ``phi_theta[i]``): the
        #: paper saw lambda_y 1.77-1.90 and lambda_theta 1.20-1.50 from shot to shot on
        #: one sheet (:func:`curltrack.discover.discover` chooses it by BIC)
        self.phi_per_shot = bool(phi_per_shot and len(shots) > 1 and baseline == "paper")
        self.R, self.r_band = rig.inertia_radius_m, rig.band_radius_m
        self.shots, self.baseline, self.cand = shots, baseline, cand
        self._sims: dict = {}
        #: (parameter values, {name: Jacobian column}) of the last Jacobian
        self._jcols: tuple | None = None
        self.values: dict = {}
        self.bounds: dict = {}
        self.free: list = []
        trans = any(s.translates for s in shots)
        spin = any(s.spins for s in shots)
        st0 = shots[0].start
        for name in SHARED:
            self.values[name] = float(np.median([s.start.get(name, st0.get(name, 0.0))
                                                 for s in shots]))
        if baseline == "dry":
            self.values["phi_y"] = self.values["phi_theta"] = 0.0
        free_shared = []
        if trans:
            free_shared += ["alpha_y"] + ([] if baseline == "dry" else ["phi_y"])
            if any(s.curls for s in shots):
                free_shared.append("a_T")
        if spin:
            free_shared += ["alpha_theta"] + ([] if baseline == "dry" else ["phi_theta"])
        # shots of one session share the ice but not the same friction (the paper's pure
        # rotations on one sheet span lambda_theta 1.55-1.66; a draw's rotation stops
        # with its translation): phi is shared, alpha is each shot's own
        self.alpha_per_shot = len(shots) > 1
        per_shot = ("alpha",) + (("phi",) if self.phi_per_shot else ())
        if self.alpha_per_shot:
            free_shared = [n for n in free_shared if not n.startswith(per_shot)]
        self.free = list(free_shared)
        for i, s in enumerate(shots):
            for law in (per_shot if self.alpha_per_shot else ()):
                for name, use in ((f"{law}_y", s.translates),
                                  (f"{law}_theta", s.spins and s.theta_measured)):
                    self.values[f"{name}[{i}]"] = float(s.start.get(name, self.values[name]))
                    if use:
                        self.free.append(f"{name}[{i}]")
            for name in PER_SHOT:
                key = f"{name}[{i}]"
                self.values[key] = float(s.start.get(name, 0.0)) if name in s.start else 0.0
                spin_fitted = s.spins or s.omega0_curl_end is not None
                if name == "omega0" and s.omega0_curl_end is not None:
                    self.values[key] = float(s.omega0_curl_end)
                use = {"v0": s.translates, "omega0": spin_fitted, "x0": s.translates,
                       "y0": s.translates, "theta0": s.spins, "skew": s.translates}[name]
                if use:
                    self.free.append(key)
        for name in self.free + list(self.values):
            spec = SHOT_MODEL[_base(name)]
            self.bounds[name] = (spec.lower, spec.upper)
        hi = float(SHOT_MODEL["omega0"].upper)
        for i, s in enumerate(shots):
            if s.omega0_curl_end is not None:   # the curl's side is the data's: kept
                self.bounds[f"omega0[{i}]"] = ((OMEGA_MIN, hi) if s.spin > 0
                                               else (-hi, -OMEGA_MIN))
        self._cand_steps = {p.name: p.step for p in cand.params if p.step is not None} \
            if cand is not None else {}
        if cand is not None:
            for p in cand.params:
                if p.name not in cand.releases:  # released baseline params keep values
                    self.values[p.name] = p.null
                self.bounds[p.name] = (p.lower, p.upper)
                if p.name not in self.free:
                    self.free.append(p.name)
        self._rows = [np.logical_or.reduce([s.use[c] for c in COORDS]) for s in shots]
        self._segments = []
        self._frame_steps = []   # frames between a segment's consecutive rows (whiten)
        i0 = 0
        for j, s in enumerate(shots):
            for c in COORDS:
                m = int(s.use[c].sum())
                if m:
                    self._segments.append((j, c, slice(i0, i0 + m)))
                    self._frame_steps.append(np.diff(s.frame[s.use[c]]))
                    i0 += m
        self.n = i0

    # --- evaluation ---------------------------------------------------------------
    @property
    def kink_params(self) -> list:
        """Free parameters that only say when something stops: a position-only shot's
        spin, whose size is known from where its curl ends.  Their derivative is a
        kink's, which a held-out refit's single Gauss-Newton step cannot follow (a fold
        that holds the curl's end moved one by 2600 sigma)."""
        return [f"omega0[{i}]" for i, s in enumerate(self.shots)
                if not s.theta_measured and s.omega0_curl_end is not None
                and f"omega0[{i}]" in self.free]

    @property
    def segments(self):
        """(shot index, coordinate, slice into the residual vector) of each segment."""
        return self._segments

    def _effect_values(self, values):
        if self.cand is None:
            return {}
        out = {p.name: values[p.name] for p in self.cand.params}
        out.update(self.cand_fixed or {})
        return out

    def predict_shot(self, values: dict, i: int, t=None) -> dict:
        """Model ``x``, ``y`` (m), ``theta`` (rad) of shot ``i`` at times ``t`` (s)."""
        s = self.shots[i]
        t = s.t if t is None else t
        v = values
        if s.theta_measured or s.omega0_curl_end is not None:
            # (position-only with the curl's end fitted: a spin under the shared rotation
            # law whose size says when it stops)
            spin = dict(omega0=v[f"omega0[{i}]"],
                        phi_theta=v.get(f"phi_theta[{i}]", v["phi_theta"]),
                        alpha_theta=v.get(f"alpha_theta[{i}]", v["alpha_theta"]))
        else:  # position-only: the curl's side, a spin that lasts as long as the slide
            spin = dict(omega0=float(s.spin), alpha_theta=None)
        model = self._ShotModel(v0=v[f"v0[{i}]"], phi_y=v.get(f"phi_y[{i}]", v["phi_y"]),
                                alpha_y=v.get(f"alpha_y[{i}]", v["alpha_y"]),
                                a_T=v["a_T"], R=self.R, r=self.r_band, **spin)
        eff = effects_for(self.cand, self._effect_values(v), i, self.shots)
        # the frame offsets and skew (4 of a shot's 6 Jacobian columns) do not change the
        # simulation: the last few per shot are reused (an extension's ODE costs ~50 ms)
        key = (i, model, tuple((e.name, tuple(e.params.items())) for e in eff))
        tr = self._sims.get(key) if t is s.t else None
        if tr is None:
            tr = self._simulate(model, effects=eff, t=t)
            if t is s.t:
                if len(self._sims) >= 4 * len(self.shots):
                    self._sims.pop(next(iter(self._sims)))
                self._sims[key] = tr
        c, sn = np.cos(v[f"skew[{i}]"]), np.sin(v[f"skew[{i}]"])
        x, y = np.asarray(tr.x), np.asarray(tr.y)
        return {"x": v[f"x0[{i}]"] + c * x - sn * y, "y": v[f"y0[{i}]"] + sn * x + c * y,
                "theta": v[f"theta0[{i}]"] + np.asarray(tr.theta)}

    def _model_vector(self, values, shots=None, cache=None):
        """Concatenated model values over the used rows (physical units)."""
        preds = list(cache) if cache is not None else [None] * len(self.shots)
        for i in range(len(self.shots)):
            if preds[i] is None or (shots is not None and i in shots):
                preds[i] = self.predict_shot(values, i, self.shots[i].t)
        out = np.empty(self.n)
        for j, c, sl in self._segments:
            out[sl] = preds[j][c][self.shots[j].use[c]]
        return out, preds

    def data_vector(self):
        out = np.empty(self.n)
        for j, c, sl in self._segments:
            out[sl] = self.shots[j].obs[c][self.shots[j].use[c]]
        return out

    def sigma_vector(self):
        out = np.empty(self.n)
        for j, c, sl in self._segments:
            out[sl] = self.shots[j].sigma[c][self.shots[j].use[c]]
        return out

    def whiten(self, v):
        """Divide by the noise and AR(1)-whiten each segment (v: (n,) or (n, k))."""
        v = np.asarray(v, dtype=float)
        out = np.empty_like(v)
        for i, (_, _, sl) in enumerate(self._segments):
            out[sl] = self.whiten_segment(i, v[sl])
        return out

    def whiten_segment(self, i: int, v):
        """:meth:`whiten` of segment ``i``'s rows alone (v: (m,) or (m, k))."""
        j, c, _ = self._segments[i]
        s = self.shots[j]
        sig = s.sigma[c][s.use[c]]
        v = np.asarray(v, dtype=float)
        return whiten(v / (sig if v.ndim == 1 else sig[:, None]), s.noise[c].rho,
                      self._frame_steps[i])

    # --- parameters -----------------------------------------------------------------
    def vector(self):
        return np.array([self.values[n] for n in self.free])

    def with_vector(self, p) -> dict:
        v = dict(self.values)
        v.update(zip(self.free, map(float, p)))
        return v

    def _affected(self, name):
        i = _shot_of(name)
        if i is not None:
            return {i}
        if self.cand is not None and self.cand.per_shot and name in \
                {p.name for p in self.cand.params}:
            return {int((self.cand_fixed or {}).get("shot", 0))}
        return None  # all shots

    def _step(self, name, value):
        st = self._cand_steps[name] if name in self._cand_steps else SHOT_MODEL[_base(name)].step
        return st if st is not None else max(1e-4 * abs(value), 1e-9)

    def jacobian_raw(self, values, base_vec=None, base_preds=None):
        """Forward-difference d(model)/d(free params) over the used rows (physical).

        The columns of the last point are kept: a column depends only on the parameter
        values, so the fit's final Jacobian (the solver's last one is usually at its
        solution) and the first of a fit that continues from there with more parameters
        free (a scanned location released) are not recomputed.
        """
        key = (tuple(sorted(values.items())),
               tuple(sorted((self.cand_fixed or {}).items())))
        if self._jcols is None or self._jcols[0] != key:
            self._jcols = (key, {})
        done = self._jcols[1]
        if base_vec is None and not all(n in done for n in self.free):
            base_vec, base_preds = self._model_vector(values)
        J = np.empty((self.n, len(self.free)))
        for k, name in enumerate(self.free):
            if name in done:
                J[:, k] = done[name]
                continue
            h = self._step(name, values[name])
            lo, hi = self.bounds[name]
            if hi is not None and values[name] + h > hi:
                h = -h
            v2 = dict(values)
            v2[name] = values[name] + h
            aff = self._affected(name)
            vec, _ = self._model_vector(v2, shots=aff, cache=None if aff is None else base_preds)
            J[:, k] = (vec - base_vec) / h
            done[name] = J[:, k].copy()
        return J

    def fit(self, max_nfev: int = 60, name: str = "<shots>", tol: float = 1e-8) -> FitOut:
        """Weighted least squares of all free parameters from the current values.

        Raises
        ------
        FitError
            The simulator fails everywhere near the start or the fit produces NaN.
        """
        data = self.data_vector()
        lo = np.array([self.bounds[n][0] if self.bounds[n][0] is not None else -np.inf
                       for n in self.free])
        hi = np.array([self.bounds[n][1] if self.bounds[n][1] is not None else np.inf
                       for n in self.free])
        p0 = np.clip(self.vector(), lo + 1e-12 * (np.abs(lo) + 1), hi - 1e-12 * (np.abs(hi) + 1))
        params = parameters(zip(self.free, zip(lo, hi), p0))
        cache = {}

        def fun(pars):
            p = vector(pars, self.free)
            vals = self.with_vector(p)
            vec, preds = self._model_vector(vals)
            cache["p"], cache["vec"], cache["preds"] = p.copy(), vec, preds
            return self.whiten(data - vec)

        def jac(pars):
            p = vector(pars, self.free)
            vals = self.with_vector(p)
            if "p" in cache and np.array_equal(cache["p"], p):
                vec, preds = cache["vec"], cache["preds"]
            else:
                vec, preds = self._model_vector(vals)
            return -self.whiten(self.jacobian_raw(vals, vec, preds))

        # trust-region reflective inside the bounds, its own Jacobian, scaled by it
        res = solve(fun, params, "least_squares", label="model fit", path=name, jac=jac,
                    max_nfev=max_nfev, nan_policy="propagate", x_scale="jac",
                    ftol=tol, xtol=tol, gtol=tol)
        self.values = self.with_vector(res.x)  # (SciPy's solution as it returned it)
        self.nfev = (res.least_squares_nfev, res.njev)
        vec, preds = self._model_vector(self.values)
        r_raw = data - vec
        r = self.whiten(r_raw)
        if not np.isfinite(r).all():
            raise FitError("model fit produced non-finite residuals", path=name)
        J_raw = self.jacobian_raw(self.values, vec, preds)
        J = self.whiten(J_raw)
        chi2 = float(r @ r)
        dof = max(self.n - len(self.free), 1)
        cov = covariance(J)
        cov = cov * max(1.0, chi2 / dof)
        return FitOut(dict(self.values), list(self.free), cov, chi2, self.n, r, J, r_raw,
                      J_raw, preds, bool(res.success), str(res.message))
