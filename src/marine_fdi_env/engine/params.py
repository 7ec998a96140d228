"""Engine parameters: a frozen dataclass with units, loaded from named parameter sets.

A parameter set is a JSON file in ``marine_fdi_env/data/params/NAME.json``.  Every entry has a
``value``, a ``unit`` and a ``source`` (a thesis table, a data sheet, or the derivation in
:mod:`marine_fdi_env.engine.calibration` that produced it).  Field names carry their SI unit as a suffix
where the quantity has one (``_Pa``, ``_K``, ``_m3``, ...).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .submodels import NO_SUBMODELS, EngineSubmodels

__all__ = [
    "engine_batch",
    "EngineParams",
    "load_params",
    "list_parameter_sets",
    "params_provenance",
    "ENGINE_FILE_FORMAT",
    "load_engine_file",
    "engine_file_dict",
]

ENGINE_FILE_FORMAT = "marine_fdi_env.engine/1"


@dataclass(frozen=True)
class EngineParams:
    """Parameters of the MVFP engine model (thesis table 4.1 plus derived values).

    Geometry and rating
    -------------------
    P_nom_W, n_nom_rev_s : nominal brake power and engine speed.
    n_cylinders : i_e.  revs_per_cycle : k_e (2 for a 4-stroke engine).
    bore_m, stroke_m, crank_rod_m : cylinder geometry (eq. B.1-B.8).
    alpha_IC_deg, alpha_EO_deg : inlet-closure and exhaust-open crank angles after TDC.
    eps_c : geometric compression ratio.  V1_m3 : cylinder volume at state 1.

    Combustion and cycle (Σ2)
    -------------------------
    SFC_nom_kg_per_J, eta_comb (η), h_L_J_per_kg, n_exp, X_cv_nom, X_cv_grad, X_ct_nom,
    p_max_nom_Pa, Q_loss_nom_Nm, Q_loss_grad, c_load_W_s3 (propeller law P = c n^3, eq. 3.11).

    Gas properties: R_a, R_g, c_v_a, c_p_a, c_p_g [J/(kg K)], kappa_a, kappa_g, sigma_f (AFR).

    Exhaust receiver and turbocharger (Σ3): tau_pd_s, A_eff_m2, alpha_z, n_bld, s_sl_nom,
    T_sl_K, m1_nom_kg, Psi_sc_nom, a_turbo, b_turbo_per_Pa, c_turbo_per_Pa2, p_ex_Pa.

    Air intake (Σ4): tau_TC_s, a_eta_per_Pa2, b_eta_per_Pa, c_eta (η_TC = a x² + b x + c,
    eq. 3.33 as corrected), eta_com, T_c_K, T_inl_K, eps_inl, p_amb_Pa, T_amb_K, p1_nom_Pa.

    Fuel pump (Σ1): tau_X_s, x1_nom_kg.

    Turbocharger speed (an output only, :mod:`marine_fdi_env.engine.turbocharger_speed`): N_tc_nom_rpm, the
    rotor speed at the isentropic compressor head dh_c_nom_J_per_kg.

    submodels : the optional extensions of the base model (:mod:`marine_fdi_env.engine.submodels`), all off by
    default.
    """

    name: str
    # rating and geometry
    P_nom_W: float
    n_nom_rev_s: float
    n_cylinders: int
    revs_per_cycle: int
    bore_m: float
    stroke_m: float
    crank_rod_m: float
    alpha_IC_deg: float
    alpha_EO_deg: float
    eps_c: float
    V1_m3: float
    # fuel pump
    SFC_nom_kg_per_J: float
    x1_nom_kg: float
    tau_X_s: float
    # combustion / Seiliger
    eta_comb: float
    h_L_J_per_kg: float
    n_exp: float
    X_cv_nom: float
    X_cv_grad: float
    X_ct_nom: float
    p_max_nom_Pa: float
    Q_loss_nom_Nm: float
    Q_loss_grad: float
    c_load_W_s3: float
    # gas properties
    R_a_J_per_kgK: float
    R_g_J_per_kgK: float
    c_v_a_J_per_kgK: float
    c_p_a_J_per_kgK: float
    c_p_g_J_per_kgK: float
    kappa_a: float
    kappa_g: float
    sigma_f: float
    # exhaust receiver and turbocharger
    tau_pd_s: float
    A_eff_m2: float
    alpha_z: float
    n_bld: float
    s_sl_nom: float
    T_sl_K: float
    m1_nom_kg: float
    Psi_sc_nom: float
    a_turbo: float
    b_turbo_per_Pa: float
    c_turbo_per_Pa2: float
    p_ex_Pa: float
    # air intake and intercooler
    tau_TC_s: float
    a_eta_per_Pa2: float
    b_eta_per_Pa: float
    c_eta: float
    eta_com: float
    T_c_K: float
    T_inl_K: float
    eps_inl: float
    p_amb_Pa: float
    T_amb_K: float
    p1_nom_Pa: float
    # turbocharger speed law (output only)
    N_tc_nom_rpm: float
    dh_c_nom_J_per_kg: float
    # optional submodels (not a float: skipped by the numeric checks)
    submodels: EngineSubmodels = NO_SUBMODELS

    def replace(self, validate: bool = True, **changes: Any) -> "EngineParams":
        """Return a copy with some fields changed (validated like a loaded set; ``validate=False`` skips the
        checks, for hot loops whose changes are valid by construction)."""
        if not validate:  # fast path: a shallow copy with the changed fields (no __init__, no checks)
            unknown = set(changes) - self.__dict__.keys()
            if unknown:
                raise TypeError(f"unknown parameter(s) {', '.join(sorted(unknown))}")
            new = object.__new__(EngineParams)
            new.__dict__.update(self.__dict__)
            new.__dict__.update(changes)
            return new
        new = dataclasses.replace(self, **changes)
        new.validate()
        return new

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first field that is not finite or out of range."""
        if not isinstance(self.submodels, EngineSubmodels):
            raise ValueError(f"parameter 'submodels' must be EngineSubmodels, got {type(self.submodels).__name__}")
        for f in dataclasses.fields(self):
            if f.name in ("name", "submodels"):
                continue
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"parameter {f.name!r} must be a finite number, got {v!r}")
        positive = [
            "P_nom_W",
            "n_nom_rev_s",
            "n_cylinders",
            "revs_per_cycle",
            "bore_m",
            "stroke_m",
            "crank_rod_m",
            "eps_c",
            "V1_m3",
            "SFC_nom_kg_per_J",
            "x1_nom_kg",
            "tau_X_s",
            "eta_comb",
            "h_L_J_per_kg",
            "p_max_nom_Pa",
            "c_load_W_s3",
            "R_a_J_per_kgK",
            "R_g_J_per_kgK",
            "c_v_a_J_per_kgK",
            "c_p_a_J_per_kgK",
            "c_p_g_J_per_kgK",
            "sigma_f",
            "tau_pd_s",
            "A_eff_m2",
            "alpha_z",
            "m1_nom_kg",
            "Psi_sc_nom",
            "p_ex_Pa",
            "tau_TC_s",
            "eta_com",
            "T_c_K",
            "T_inl_K",
            "p_amb_Pa",
            "T_amb_K",
            "p1_nom_Pa",
            "T_sl_K",
            "N_tc_nom_rpm",
            "dh_c_nom_J_per_kg",
        ]
        for key in positive:
            if getattr(self, key) <= 0:
                raise ValueError(f"parameter {key!r} must be > 0, got {getattr(self, key)!r}")
        for key in ("kappa_a", "kappa_g", "n_exp", "n_bld"):
            if getattr(self, key) <= 1:
                raise ValueError(f"parameter {key!r} must be > 1, got {getattr(self, key)!r}")
        if not 0 <= self.X_ct_nom < 1 or not 0 <= self.X_cv_nom < 1:
            raise ValueError("parameters 'X_cv_nom' and 'X_ct_nom' must lie in [0, 1)")


def _params_dir():
    return resources.files("marine_fdi_env") / "data" / "params"


def list_parameter_sets() -> list[str]:
    """Names of the parameter sets shipped with the package."""
    return sorted(p.name[:-5] for p in _params_dir().iterdir() if p.name.endswith(".json"))


@lru_cache(maxsize=None)
def _raw(name: str) -> dict[str, Any]:
    names = list_parameter_sets()
    if name not in names:
        raise ValueError(f"unknown parameter set {name!r}; allowed: {', '.join(names)}")
    with (_params_dir() / f"{name}.json").open() as fh:
        return json.load(fh)


def params_provenance(name: str) -> dict[str, dict[str, Any]]:
    """Value, unit and source of every parameter of a shipped set."""
    return dict(_raw(name)["parameters"])


def params_from_dict(name: str, entries: dict[str, Any]) -> EngineParams:
    """Build and validate :class:`EngineParams` from ``{field: value or {"value": ...}}``."""
    names = {f.name for f in dataclasses.fields(EngineParams)} - {"name", "submodels"}
    values = {k: (v["value"] if isinstance(v, dict) else v) for k, v in entries.items()}
    missing = sorted(names - values.keys())
    unknown = sorted(values.keys() - names)
    if missing:
        raise ValueError(f"parameter set {name!r} lacks fields: {', '.join(missing)}")
    if unknown:
        raise ValueError(f"parameter set {name!r} has unknown fields: {', '.join(unknown)}")
    p = EngineParams(name=name, **values)
    p.validate()
    return p


def load_params(name: "str | Path | EngineParams" = "thesis-12v28") -> EngineParams:
    """A parameter set: a shipped one by name (``thesis-12v28``, ``man-12v32-40``, ``wartsila-6l46``), or a
    fitted-engine file ``FILE.json`` (base set + submodels, written by ``marine-fdi validate --save-params``;
    see :func:`load_engine_file`).  An :class:`EngineParams` is returned as it is."""
    if isinstance(name, EngineParams):
        return name
    if isinstance(name, Path) or (isinstance(name, str) and name.endswith(".json")):
        return load_engine_file(name)
    if not isinstance(name, str):
        raise ValueError(f"parameter set must be a name, a .json file or EngineParams, got {name!r}")
    return _load_shipped(name)


def engine_batch(params: "str | EngineParams", n_engines, dt) -> tuple[EngineParams, int, float]:
    """``(parameter set, n_engines, dt)`` of a batch of engines, checked (a positive number of engines, a
    positive finite sample time [s]); a parameter-set name is loaded."""
    p = load_params(params) if isinstance(params, str) else params
    if not isinstance(n_engines, (int, np.integer)) or n_engines < 1:
        raise ValueError(f"n_engines must be a positive integer, got {n_engines!r}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite number of seconds, got {dt!r}")
    return p, int(n_engines), float(dt)


@lru_cache(maxsize=None)
def _load_shipped(name: str) -> EngineParams:
    return params_from_dict(name, _raw(name)["parameters"])


def engine_file_dict(params: EngineParams, base: str, provenance: dict[str, Any] | None = None) -> dict[str, Any]:
    """The fitted-engine file of ``params``: the base set's name, the parameters that differ from it
    and the submodels, with ``provenance`` (what fitted it, on which data)."""
    ref = _load_shipped(base)
    overrides = {}
    for f in dataclasses.fields(EngineParams):
        if f.name in ("name", "submodels"):
            continue
        if getattr(params, f.name) != getattr(ref, f.name):
            overrides[f.name] = getattr(params, f.name)
    return {
        "format": ENGINE_FILE_FORMAT,
        "name": params.name,
        "base": base,
        "overrides": overrides,
        "submodels": params.submodels.to_dict(),
        "provenance": provenance or {},
    }


def load_engine_file(path: "str | Path") -> EngineParams:
    """Load a fitted-engine file: ``{"format": "marine_fdi_env.engine/1", "name", "base", "overrides":
    {field: value}, "submodels": {...}, "provenance": {...}}``.  Errors name the file and the field."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(
            f"no such engine file {str(path)!r} (give a shipped set: "
            f"{', '.join(list_parameter_sets())}, or a file written by 'marine-fdi validate "
            "--save-params')"
        ) from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON: {e}") from None
    if not isinstance(d, dict) or d.get("format") != ENGINE_FILE_FORMAT:
        raise ValueError(f'{path}: not an engine file (expected "format": "{ENGINE_FILE_FORMAT}")')
    base = d.get("base")
    if base not in list_parameter_sets():
        raise ValueError(
            f"{path}: field 'base' must name a shipped parameter set ({', '.join(list_parameter_sets())}), got {base!r}"
        )
    overrides = d.get("overrides") or {}
    names = {f.name for f in dataclasses.fields(EngineParams)} - {"name", "submodels"}
    bad = sorted(set(overrides) - names)
    if bad:
        raise ValueError(f"{path}: unknown parameter(s) in 'overrides': {', '.join(bad)}")
    try:
        sub = EngineSubmodels.from_dict(d.get("submodels"))
        return _load_shipped(base).replace(name=str(d.get("name") or path.stem), submodels=sub, **overrides)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
