"""What :func:`curltrack.discover.discover` returns: a frozen report of frozen findings.

``summary()`` of each is the REPORT.json mapping of the contract, key for key; the report
also reads like that mapping (``report["verdict"]``, ``report["findings"][0]["effect"]``),
while its attributes hold typed values and, for the figure, the fitted models
(lmfit's habit: a result object that prints, serialises and plots).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

#: REPORT.json keys of a candidate's finding, in order (``loso_*`` and
#: ``structure_after`` only when the candidate was refitted)
_CANDIDATE_KEYS = ("effect", "delta_bic", "delta_bic_linear", "threshold", "bootstrap",
                   "location_start", "rms_before", "rms_after", "heldout_rmse_before",
                   "heldout_rmse_after", "heldout_before_by_coord", "heldout_after_by_coord",
                   "params", "params_err", "note", "nfev")
_UNEXPLAINED_KEYS = ("effect", "delta_bic", "rms_before", "rms_after", "heldout_rmse_before",
                     "heldout_rmse_after", "params", "params_err", "where", "evidence")


def format_limits(limits) -> str:
    """A finding's ``detection_limit`` mapping in words: ``|name - null| median unit``
    per size parameter ("" for none)."""
    parts = []
    for name, v in (limits or {}).items():
        size = f"{name} - {v['null']:g}" if v.get("null") else name
        unit = f" {v['unit']}" if v.get("unit") else ""
        parts.append(f"|{size}| {v['median']:.2g}{unit}")
    return ", ".join(parts)


@dataclass(frozen=True)
class Finding:
    """One candidate effect as measured (or the ``unexplained`` residual structure).

    Attributes
    ----------
    effect : str
        Effect name, or ``"unexplained"``.
    delta_bic : float
        BIC of the baseline minus that of the extended model (> 0: the effect pays).
    rms_before, rms_after : dict
        RMS residual per coordinate (m, m, rad) of the baseline / the extended model.
    heldout_rmse_before, heldout_rmse_after : float
        Blocked cross-validation RMS (noise units).
    params, params_err : dict
        Fitted effect parameters and their 1σ (contract names and units).
    evidence : str
        The reason, in words.
    supported : bool
        delta-BIC above 0 and the bootstrap threshold, and a better held-out error.
    delta_bic_linear, threshold, bootstrap, location_start, heldout_*_by_coord, note,
    nfev, loso_rmse_before, loso_rmse_after, structure_after
        A candidate's scan and refit (None when not refitted or not applicable).
    not_named_because : list of str or None
        For a supported candidate, what keeps it from being named (a parameter at its
        bound, a coordinate's RMS made worse); empty when nothing does.
    detection_limit : dict or None
        Per size parameter, the smallest size (distance from its null value, in its
        unit) that the candidate's threshold lets be seen, over its scan's locations:
        ``median``, ``min``, ``max``, ``unit``.  A `none` says nothing about effects of
        that size or smaller; the linearised scan's, so a lower bound on what is named
        (the refit and the held-out test ask more).
    where : dict or None
        Where the unexplained misfit sits (``unexplained`` only).
    delta_bic_without_few_rows : float or None
        The refitted candidate's delta-BIC without the 3 frames that carry most of its
        gain (it must clear the bootstrap's ``threshold_few_rows`` too).
    path_change_stated : float or None
        The largest change the candidate makes to the fitted path, in units of the sigma
        the instrument states for its rows (only where every coordinate's errors persist
        and are stated: 2 or less is not supported).
    fit : object
        The extended model's fit (``FitOut``), for figures; not serialised.
    """

    effect: str
    delta_bic: float
    rms_before: dict
    rms_after: dict | None
    heldout_rmse_before: float
    heldout_rmse_after: float | None
    params: dict
    params_err: dict
    evidence: str
    supported: bool = False
    delta_bic_linear: float | None = None
    threshold: float | None = None
    bootstrap: dict | None = None
    location_start: dict | None = None
    heldout_before_by_coord: dict | None = None
    heldout_after_by_coord: dict | None = None
    note: str | None = None
    nfev: tuple | None = None
    loso_rmse_before: float | None = None
    loso_rmse_after: float | None = None
    structure_after: dict | None = None
    not_named_because: list | None = None
    extension: bool | None = None
    detection_limit: dict | None = None
    where: dict | None = None
    delta_bic_without_few_rows: float | None = None
    path_change_stated: float | None = None
    fit: object = field(default=None, compare=False, repr=False)

    @property
    def named(self) -> bool:
        """A candidate effect (not the ``unexplained`` residual structure)."""
        return self.effect != "unexplained"

    def summary(self) -> dict:
        """The REPORT.json mapping of this finding (contract keys, in order)."""
        if not self.named:
            return {k: getattr(self, k) for k in _UNEXPLAINED_KEYS}
        out = {k: getattr(self, k) for k in _CANDIDATE_KEYS}
        if self.loso_rmse_after is not None:
            out["loso_rmse_before"] = self.loso_rmse_before
            out["loso_rmse_after"] = self.loso_rmse_after
        if self.structure_after is not None:
            out["structure_after"] = self.structure_after
        for k in ("delta_bic_without_few_rows", "path_change_stated"):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        out["supported"] = self.supported
        if self.not_named_because is not None:
            out["not_named_because"] = self.not_named_because
        if self.extension:
            out["extension"] = True
        if self.detection_limit:
            out["detection_limit"] = self.detection_limit
        out["evidence"] = self.evidence
        return out


@dataclass(frozen=True)
class DiscoveryReport(Mapping):
    """The outcome of :func:`curltrack.discover.discover` (REPORT.json, typed).

    Attributes
    ----------
    verdict : str
        The named effect, ``"extended"``, ``"none"`` or ``"unexplained"``.
    findings : tuple of Finding
        Sorted by delta-BIC, largest first.
    baseline : dict
        The baseline model's parameters, errors, RMS, BIC, chi-square, held-out error.
    unexplained : dict or None
        Where the misfit sits, when the verdict is ``unexplained``.
    structure_before : dict
        Residual structure tests of the baseline.
    noise : list of dict
        The noise model of every shot and coordinate.
    shots : list of dict
        Per shot: file, spin, stops, heading.
    warnings : list of str
    not_tested : dict
        Effects these shots cannot tell from the baseline, and why.
    extension : dict or None
        The data-driven extension of the equations (verdict ``extended``).
    shot_data, model, fit0, best_fit, extended, best_params
        The fitted objects behind the figure (not serialised): the prepared shots, the
        baseline model, its fit, the fit of the named (or best supported) extension, its
        name and parameters.
    """

    verdict: str
    findings: tuple
    baseline: dict
    unexplained: dict | None
    structure_before: dict
    noise: list
    shots: list
    warnings: list
    not_tested: dict = field(default_factory=dict)
    extension: dict | None = None
    shot_data: list = field(default_factory=list, compare=False, repr=False)
    model: object = field(default=None, compare=False, repr=False)
    fit0: object = field(default=None, compare=False, repr=False)
    best_fit: object = field(default=None, compare=False, repr=False)
    extended: str | None = field(default=None, compare=False, repr=False)
    best_params: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def success(self) -> bool:
        """A cause was named (the verdict is an effect)."""
        return self.verdict not in ("none", "unexplained")  # named or extended

    def limits_text(self) -> str:
        """Each candidate's detection limits in words (medians over its scan's places):
        what a ``none`` cannot speak for (:attr:`Finding.detection_limit`)."""
        return "; ".join(f"{f.effect} {format_limits(f.detection_limit)}"
                         for f in self.findings if f.detection_limit)

    @property
    def bic(self) -> float:
        """BIC of the baseline."""
        return self.baseline["bic"]

    def summary(self) -> dict:
        """The REPORT.json mapping (contract keys, in order; NaN/inf as the writer
        leaves them to :func:`curltrack._atomic.write_json`)."""
        return {"baseline": self.baseline, "findings": [f.summary() for f in self.findings],
                "verdict": self.verdict, "extension": self.extension,
                "unexplained": self.unexplained,
                "structure_before": self.structure_before, "noise": self.noise,
                "shots": self.shots, "warnings": self.warnings,
                "not_tested": self.not_tested}

    # read like the REPORT.json mapping
    def __getitem__(self, key):
        return self.summary()[key]

    def __iter__(self):
        return iter(self.summary())

    def __len__(self) -> int:
        return len(self.summary())
