"""Glove profile (per glove) and session calibration (per wearing) files (docs/glove.md).

- :class:`GloveProfile`: thumb parallelogram slopes (and default intercepts), dynamic
  zero-abduction parameters of the three spread sensors, spread angle range, the thumb's unmeasured
  sideways default, optional joint-range overrides.  Fitted once per glove; kept by the user.
- :class:`SessionCalibration`: per-sensor min/max and the session's thumb intercepts, written by
  ``handflow calibrate`` (:func:`calibrate_session`).

Both are YAML or JSON (by suffix), validated by pydantic; a missing or broken file raises
:class:`CalibrationFileError` saying which file and what to change.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

import numpy as np
import yaml
from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator

from handflow.framework.files.params import StrictModel
from handflow.framework.files.resources import shipped
from handflow.framework.files.yaml import YamlFileError, load_model
from handflow.plugins.hands.sensors import N_SENSORS, SENSOR_NAMES, sensor_index

from .parallelogram import fit_intercepts, robust_extremes

SPREAD_SENSORS = {
    "index_middle_abduction": ("index_mcp", "middle_mcp"),
    "middle_ring_abduction": ("middle_mcp", "ring_mcp"),
    "ring_little_abduction": ("ring_mcp", "little_mcp"),
}
"""Spread sensor → (left, right) neighbouring flex sensors that shape its zero level."""

THESIS_INTERCEPTS = (249.0, 244.0, 572.0, 147.0)
DEFAULT_CONFIG_DIR = shipped("glove")
DEFAULT_PROFILE = DEFAULT_CONFIG_DIR / "default_profile.yaml"
DEFAULT_CALIBRATION = DEFAULT_CONFIG_DIR / "default_calibration.yaml"
"""Shipped defaults (configs/glove/)."""


class CalibrationFileError(ValueError):
    """A glove profile or session calibration file that is missing or invalid."""


class ZeroAbduction(StrictModel):
    """Height ``h`` and shape ``lam`` = (λ1…λ6) of a zero-abduction surface (see zero_abduction.py)."""

    h: float
    lam: tuple[float, float, float, float, float, float] = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)

    @field_validator("lam")
    @classmethod
    def _positive_scales(cls, lam):
        if lam[0] <= 0 or lam[3] <= 0:
            raise ValueError("λ1 (rotation weight) and λ4 (width) must be > 0")
        return lam


class GloveProfile(StrictModel):
    """Per-glove mapping parameters."""

    name: str = "default"
    thumb_m13: float = Field(description="slope of the left/right parallelogram sides (s4 over s1)")
    thumb_m24: float = Field(description="slope of the top/bottom parallelogram sides")
    thumb_intercepts: tuple[float, float, float, float] = THESIS_INTERCEPTS
    zero_abduction: dict[str, ZeroAbduction]
    spread_phi_min_deg: float = -11.0
    spread_phi_max_deg: float = 60.0
    th_mcp_side_deg: float = 0.0
    joint_ranges_deg: dict[str, tuple[float, float]] = Field(
        default_factory=dict, description="overrides of (θ_min, θ_max) for mapped human joints"
    )

    @model_validator(mode="after")
    def _check(self):
        missing = set(SPREAD_SENSORS) - set(self.zero_abduction)
        extra = set(self.zero_abduction) - set(SPREAD_SENSORS)
        if missing or extra:
            raise ValueError(
                f"zero_abduction needs exactly the keys {sorted(SPREAD_SENSORS)}"
                f" (missing {sorted(missing)}, unknown {sorted(extra)})"
            )
        if abs(self.thumb_m13 - self.thumb_m24) < 1e-6:
            raise ValueError("thumb_m13 and thumb_m24 must differ (parallel sides make no parallelogram)")
        return self


class SessionCalibration(StrictModel):
    """Per-session calibration: sensor extremes and thumb parallelogram intercepts (b1, b2, b3, b4)."""

    profile: str = "default"
    s_min: list[float]
    s_max: list[float]
    thumb_intercepts: tuple[float, float, float, float]
    n_samples: int = 0
    rejected: dict[str, int] = Field(default_factory=dict, description="samples beyond the robust extremes")
    created: str = ""

    @model_validator(mode="after")
    def _check(self):
        if len(self.s_min) != N_SENSORS or len(self.s_max) != N_SENSORS:
            raise ValueError(
                f"s_min and s_max need {N_SENSORS} values (one per sensor), got {len(self.s_min)} and {len(self.s_max)}"
            )
        flat = [SENSOR_NAMES[i] for i in range(N_SENSORS) if self.s_max[i] <= self.s_min[i]]
        if flat:
            raise ValueError(
                f"s_max must exceed s_min for every sensor; not for: {', '.join(flat)} "
                "(move these joints through their full range while calibrating)"
            )
        return self

    @property
    def lo(self) -> np.ndarray:
        return np.asarray(self.s_min, dtype=float)

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.s_max, dtype=float)


def _load(path: str | Path, model: type[BaseModel], what: str):
    p = Path(path)
    if not p.is_file():
        raise CalibrationFileError(
            f"{what} file '{p}' not found; pass an existing file (defaults ship in "
            "configs/glove/) or record one with 'handflow calibrate'"
        )
    if p.suffix.lower() != ".json":
        try:
            return load_model(p, model)
        except YamlFileError as exc:
            raise CalibrationFileError(f"{what} file is invalid — fix:\n{exc}") from None
    try:
        data = json.loads(p.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise CalibrationFileError(f"{what} file '{p}' is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise CalibrationFileError(f"{what} file '{p}' must hold a mapping of fields, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        errors = "; ".join(f"{'.'.join(map(str, e['loc'])) or '(file)'}: {e['msg']}" for e in exc.errors())
        raise CalibrationFileError(f"{what} file '{p}' is invalid — fix: {errors}") from None


def load_profile(path: str | Path) -> GloveProfile:
    return _load(path, GloveProfile, "glove profile")


def load_calibration(path: str | Path) -> SessionCalibration:
    return _load(path, SessionCalibration, "session calibration")


def save(model: BaseModel, path: str | Path) -> Path:
    """Write a profile or calibration as YAML (or JSON for a ``.json`` suffix)."""
    p = Path(path)
    data = model.model_dump(mode="json")
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(data, indent=2) if p.suffix.lower() == ".json" else yaml.safe_dump(data, sort_keys=False))
    return p


def calibrate_session(frames, profile: GloveProfile, support: int = 5) -> SessionCalibration:
    """Session calibration from raw frames (n, 22): robust per-sensor extremes (the ``support``-th
    smallest/largest reading) and the thumb intercepts (method 2, the profile's slopes)."""
    frames = np.asarray(frames, dtype=float)
    if frames.ndim != 2 or frames.shape[1] != N_SENSORS:
        raise ValueError(f"raw frames must have shape (n, {N_SENSORS}), got {frames.shape}")
    lo, hi, rejected = robust_extremes(frames, support)
    para, thumb_rejected = fit_intercepts(
        frames[:, sensor_index("thumb_roll")],
        frames[:, sensor_index("thumb_abduction")],
        profile.thumb_m13,
        profile.thumb_m24,
        support,
    )
    report = {SENSOR_NAMES[i]: int(r) for i, r in enumerate(rejected) if r}
    report["thumb_parallelogram"] = thumb_rejected
    return SessionCalibration(
        profile=profile.name,
        s_min=lo.tolist(),
        s_max=hi.tolist(),
        thumb_intercepts=(float(para.b1), float(para.b2), float(para.b3), float(para.b4)),
        n_samples=len(frames),
        rejected=report,
        created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    )
