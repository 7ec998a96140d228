"""Derivation of the parameters that thesis table 4.1 lacks, from the nominal operating point.

The thesis engine (MAN 12V28/33D) is specified by its nominal point: 5.4 MW at 16.71 rev/s,
p1 = 4.1 bar, p_max = 188 bar, SFC = 5.5e-8 kg/J.  Table 4.1 does not list the turbine area,
the friction torque, the propeller-law constant, the turbine efficiency, the slip-air temperature,
the nominal trapped mass and scavenge flow function.  Each is derived here so that the model's
steady state at fuel setting 1.0 *is* that nominal point (``derive_parameters``):

1. ``x1_nom`` from eq. 3.5 (2.962e-3 kg; table 4.1 rounds it to 3e-3).
2. ``c_load = P_nom / n_nom³`` so that the propeller law (eq. 3.11) passes through the point.
3. ``T1_nom`` from eq. 3.37 (corrected sign), ``m1_nom = p1_nom V1 / (R_a T1_nom)``.
4. **Calibration of X_cv_nom.**  With table 4.1 (X_cv = 0.06017, r_c = 12.5 from eq. B.1-B.8)
   the cycle gives p_max = 158 bar, not the stated 188 bar.  p_max = p1 r_c^κa T3/T2 fixes
   T3, hence ``X_cv_nom = c_v (T3 - T2) / q`` in closed form (about 0.17).  X_cv is the one
   cycle parameter that sets the peak pressure without touching the charge state, and it is an
   empirical combustion-shape parameter that is normally fitted to p_max.
5. ``Q_loss_nom = Q_indicated - P_nom / (2π n_nom)``: the friction torque that makes the brake
   power (hence SFC) nominal.
6. Turbine efficiency η_turbo (eq. 3.26): chosen proportional to η_TC (eq. 3.33),
   ``η_turbo = η_TC / (η_c η_com)`` with a constant compressor isentropic efficiency η_c
   (``eta_c_nom``), so eq. 3.38 is isentropic compression at η_c.
7. The exhaust receiver pressure p_d at the nominal point is the root of the turbocharger
   balance ``p_amb π(p_d) = p1_nom`` (eq. 3.31); then ``Psi_sc_nom = Ψ(p_d/p1_nom)`` (eq. 3.19)
   and the turbine effective area from the flow law (eq. 3.16)
   ``A_eff = ṁ_g sqrt(R_g z1^(3) / (p_d² - p_ex²)) / α_z``.

8. Turbocharger speed (an output, :mod:`marine_fdi_env.engine.turbocharger_speed`): the rated rotor speed
   ``N_tc_nom_rpm`` at the isentropic compressor head ``dh_c_nom_J_per_kg``.  For wartsila-6l46 both
   come from one reading, the 100 % row of the Birka ME1 test protocol (the only turbocharger-speed
   record we have); the other sets scale it by similarity (same isentropic head coefficient, compressor
   diameter growing with the square root of the volume flow per turbocharger).

Choices that no data determines are passed in as inputs with their justification (the
``source`` text of the entry): η_com, η_c, Q_loss_grad, σ_f, T_sl, turbochargers per engine.

The repository's parameter-set command (docs/model.md) rewrites the shipped parameter sets from
the input tables below (:func:`write_parameter_sets`); ``tests/unit/test_params.py`` checks that the shipped
files match.
"""

from __future__ import annotations

import json
import math
from dataclasses import fields
from pathlib import Path
from typing import Any

from scipy.optimize import brentq

from .geometry import cylinder_geometry
from .params import EngineParams

__all__ = ["derive_parameters", "INPUT_SETS", "write_parameter_sets"]

Entry = dict[str, Any]  # {"value": float, "unit": str, "source": str}

T41 = "thesis table 4.1"


def _e(value: float, unit: str, source: str) -> Entry:
    return {"value": value, "unit": unit, "source": source}


THESIS_12V28: dict[str, Entry] = {
    "P_nom_W": _e(5400e3, "W", T41),
    "n_nom_rev_s": _e(16.71, "rev/s", T41),
    "n_cylinders": _e(12, "-", T41),
    "revs_per_cycle": _e(2, "-", T41 + " (4-stroke)"),
    "bore_m": _e(0.28, "m", T41),
    "stroke_m": _e(0.33, "m", T41),
    "crank_rod_m": _e(0.64063, "m", T41),
    "alpha_IC_deg": _e(224.0, "deg", T41),
    "alpha_EO_deg": _e(119.0, "deg", T41),
    "eps_c": _e(13.8, "-", T41),
    "V1_m3": _e(0.0199, "m3", T41),
    "SFC_nom_kg_per_J": _e(5.5e-8, "kg/J", T41),
    "tau_X_s": _e(0.015, "s", T41 + "; equals 1/(4 n_nom) of eq. 3.4"),
    "eta_comb": _e(0.886, "-", T41),
    "h_L_J_per_kg": _e(42700e3, "J/kg", T41),
    "n_exp": _e(1.38, "-", T41),
    "X_cv_grad": _e(-0.4164, "-", T41),
    "X_ct_nom": _e(0.4, "-", T41),
    "p_max_nom_Pa": _e(188e5, "Pa", T41),
    "R_a_J_per_kgK": _e(287.0, "J/(kg K)", T41),
    "R_g_J_per_kgK": _e(271.0, "J/(kg K)", T41),
    "c_v_a_J_per_kgK": _e(717.5, "J/(kg K)", T41),
    "c_p_a_J_per_kgK": _e(1005.0, "J/(kg K)", T41),
    "c_p_g_J_per_kgK": _e(1100.0, "J/(kg K)", T41),
    "kappa_a": _e(1.4, "-", T41),
    "kappa_g": _e(1.353, "-", T41),
    "sigma_f": _e(14.5, "-", "choice: stoichiometric air/fuel ratio of marine diesel oil (thesis silent)"),
    "tau_pd_s": _e(0.01, "s", T41),
    "alpha_z": _e(1.0, "-", "thesis text after eq. 3.26 (constant-pressure turbocharging)"),
    "n_bld": _e(1.38, "-", T41 + " (n_bln)"),
    "s_sl_nom": _e(0.1719, "-", T41),
    "p_ex_Pa": _e(1e5, "Pa", "thesis text after eq. 3.26: equal to the ambient pressure"),
    "tau_TC_s": _e(51.0, "s", T41),
    "a_eta_per_Pa2": _e(-3.29e-12, "1/Pa^2", T41 + " (quadratic coefficient, see eq. 3.33 note)"),
    "b_eta_per_Pa": _e(2.52e-6, "1/Pa", T41 + " with sign corrected to +, see air_intake.py"),
    "c_eta": _e(0.2143, "-", T41 + " (constant term)"),
    "eta_com": _e(0.97, "-", "choice: turbocharger mechanical efficiency, typical 0.95-0.98 (thesis silent)"),
    "T_c_K": _e(323.0, "K", T41),
    "T_inl_K": _e(423.0, "K", T41),
    "eps_inl": _e(0.05, "-", T41),
    "p_amb_Pa": _e(1e5, "Pa", T41),
    "T_amb_K": _e(318.0, "K", T41 + " (tropical design conditions)"),
    "p1_nom_Pa": _e(4.1e5, "Pa", T41),
    "Q_loss_grad": _e(
        -0.5,
        "-",
        "choice: half of the friction torque is independent of speed and half proportional to it "
        "(friction mean effective pressure linear in mean piston speed); thesis silent",
    ),
}

# Design choices used by the derivation but not stored as model parameters.
THESIS_CHOICES = {
    "eta_c_nom": _e(0.85, "-", "choice: compressor isentropic efficiency of a modern turbocharger"),
    "T_sl_is_T1": _e(1.0, "-", "choice: slip air leaves at the inlet-air temperature T1 (eq. 3.37)"),
}


def _scaled(base: dict[str, Entry], name: str, changes: dict[str, Entry]) -> dict[str, Entry]:
    out = {}
    for k, v in base.items():
        out[k] = changes.get(k, {**v, "source": f"same value as thesis-12v28 ({v['source']})"})
    for k in changes:
        if k not in out:
            out[k] = changes[k]
    return out


def _sibling(
    name: str,
    bore: float,
    stroke: float,
    n_cyl: int,
    P: float,
    rpm: float,
    sfc: float,
    p1: float,
    T_amb: float,
    T_c: float,
    src: str,
    extra: dict[str, Entry],
) -> dict[str, Entry]:
    """Input set of a sibling engine: geometry and rating from public data, the rest scaled."""
    base = THESIS_12V28
    n = rpm / 60.0
    scale = (bore / base["bore_m"]["value"]) ** 2 * (stroke / base["stroke_m"]["value"])
    changes = {
        "P_nom_W": _e(P, "W", src),
        "n_nom_rev_s": _e(n, "rev/s", src),
        "n_cylinders": _e(n_cyl, "-", src),
        "bore_m": _e(bore, "m", src),
        "stroke_m": _e(stroke, "m", src),
        "crank_rod_m": _e(
            base["crank_rod_m"]["value"] * stroke / base["stroke_m"]["value"],
            "m",
            "scaled from thesis-12v28 at the same stroke/rod ratio",
        ),
        "V1_m3": _e(base["V1_m3"]["value"] * scale, "m3", "scaled from thesis-12v28 with bore² x stroke"),
        "SFC_nom_kg_per_J": _e(sfc, "kg/J", src),
        "tau_X_s": _e(1.0 / (4.0 * n), "s", "eq. 3.4: 1/(4 n_nom)"),
        "p1_nom_Pa": _e(p1, "Pa", src),
        "T_amb_K": _e(T_amb, "K", src),
        "T_c_K": _e(T_c, "K", src),
        **extra,
    }
    return _scaled(base, name, changes)


MAN_SRC = "MAN 32/40 project guide, table 73/29 (shared/data/man_12v32_40_fpp_iso.meta.json)"
BIRKA_SRC = "Birka Stockholm shop tests, 100 % load mean of ME1-ME3 (shared/data/birka_6l46_shop_test.csv)"
PROTOCOL_SRC = (
    "Birka ME1 test protocol, 100 % row (shared/data/birka_me1_test_protocol.csv): turbocharger speed "
    "22142 rpm at charge-air pressure 3.08 bar gauge, ambient 1025 hPa, compressor inlet 34 C; the one "
    "reading the turbocharger-speed law is calibrated on"
)
# The 100 % row of the protocol: the calibration point of the turbocharger-speed law of wartsila-6l46.
PROTOCOL_TC_POINT = {"N_rpm": 22142.0, "p_ca_gauge_Pa": 3.08e5, "p_amb_Pa": 1025e2, "T_inlet_K": 34.0 + 273.15}
# Turbochargers per engine (choice: one per row of six cylinders; thesis and project guide silent).
TURBOCHARGERS = {"thesis-12v28": 2, "man-12v32-40": 2, "wartsila-6l46": 1}

INPUT_SETS: dict[str, dict[str, Entry]] = {
    "thesis-12v28": THESIS_12V28,
    "man-12v32-40": _sibling(
        "man-12v32-40",
        0.32,
        0.40,
        12,
        5400e3,
        750.0,
        sfc=187e-3 / 3.6e6,
        p1=4.06e5,
        T_amb=298.15,
        T_c=316.15,
        src=MAN_SRC,
        extra={
            "p_amb_Pa": _e(1e5, "Pa", MAN_SRC + ": ISO conditions"),
            "p_ex_Pa": _e(1e5, "Pa", "equal to the ambient pressure"),
        },
    ),
    "wartsila-6l46": _sibling(
        "wartsila-6l46",
        0.46,
        0.58,
        6,
        5890e3,
        500.0,
        sfc=(1141.0 + 1165.1 + 1152.0) / 3 / 3600.0 / 5890e3,
        p1=(3.15 + 3.04 + 3.11) / 3 * 1e5 + 1.013e5,
        T_amb=298.15,
        T_c=THESIS_12V28["T_c_K"]["value"],
        src=BIRKA_SRC,
        extra={
            "p_amb_Pa": _e(1.013e5, "Pa", "choice: standard atmosphere (ambient not recorded)"),
            "p_ex_Pa": _e(1.013e5, "Pa", "equal to the ambient pressure"),
        },
    ),
}
INPUT_SETS["wartsila-6l46"]["T_amb_K"]["source"] = "choice: ISO 25 C (ambient not recorded in the shop tests)"
INPUT_SETS["wartsila-6l46"]["T_c_K"]["source"] = (
    "same value as thesis-12v28 (thesis table 4.1): the shop tests record no cooler-outlet temperature"
)


def derive_parameters(name: str, inputs: dict[str, Entry], choices: dict[str, Entry] | None = None) -> dict[str, Entry]:
    """Complete a set of table inputs with the derived parameters (module docstring, steps 1-7)."""
    from .constants import model_constants
    from .seiliger import seiliger_cycle
    from .subsystems.exhaust_receiver import scavenge_flow_function

    choices = choices or THESIS_CHOICES
    v = {k: e["value"] for k, e in inputs.items()}
    out = dict(inputs)
    P, n = v["P_nom_W"], v["n_nom_rev_s"]
    x1 = v["SFC_nom_kg_per_J"] * P * v["revs_per_cycle"] / (v["n_cylinders"] * n)
    out["x1_nom_kg"] = _e(x1, "kg", "eq. 3.5: SFC P k_e / (i_e n)")
    out["c_load_W_s3"] = _e(P / n**3, "W s^3", "eq. 3.11 through the nominal point: P_nom / n_nom^3")
    T1 = v["T_c_K"] + v["eps_inl"] * (v["T_inl_K"] - v["T_c_K"])
    p1 = v["p1_nom_Pa"]
    m1 = p1 * v["V1_m3"] / (v["R_a_J_per_kgK"] * T1)
    out["m1_nom_kg"] = _e(m1, "kg", "eq. 3.29 at the nominal point: p1_nom V1 / (R_a T1_nom)")
    out["T_sl_K"] = _e(T1, "K", choices["T_sl_is_T1"]["source"])
    g = cylinder_geometry(
        v["bore_m"], v["stroke_m"], v["crank_rod_m"], v["eps_c"], v["alpha_IC_deg"], v["alpha_EO_deg"]
    )
    ka, cv = v["kappa_a"], v["c_v_a_J_per_kgK"]
    q = v["eta_comb"] * v["h_L_J_per_kg"] * x1 / m1
    T2 = T1 * g.r_c ** (ka - 1.0)
    T3 = T2 * v["p_max_nom_Pa"] / (p1 * g.r_c**ka)
    X_cv = cv * (T3 - T2) / q
    out["X_cv_nom"] = _e(
        X_cv,
        "-",
        "calibrated to p_max_nom (for thesis-12v28, table 4.1's 0.06017 yields p_max = 158 bar): closed form "
        "from p_max_nom = p1 r_c^ka T3/T2 with T3 = T2 + X_cv q / c_v",
    )
    eta_c = choices["eta_c_nom"]["value"]
    denom = eta_c * v["eta_com"]
    src_t = f"eq. 3.26: eta_TC coefficient / (eta_c eta_com), eta_c = {eta_c} ({choices['eta_c_nom']['source']})"
    out["a_turbo"] = _e(v["c_eta"] / denom, "-", src_t)
    out["b_turbo_per_Pa"] = _e(v["b_eta_per_Pa"] / denom, "1/Pa", src_t)
    out["c_turbo_per_Pa2"] = _e(v["a_eta_per_Pa2"] / denom, "1/Pa^2", src_t)

    # Provisional complete parameter set to evaluate the subsystems at the nominal point.
    prov = {k: e["value"] for k, e in out.items()}
    prov.update(Q_loss_nom_Nm=0.0, A_eff_m2=1.0, Psi_sc_nom=1.0)
    prov.update(N_tc_nom_rpm=1.0, dh_c_nom_J_per_kg=1.0)
    P0 = EngineParams(
        name=name, **{f.name: prov[f.name] for f in fields(EngineParams) if f.name not in ("name", "submodels")}
    )
    c0 = model_constants(P0)
    X_ct = v["X_ct_nom"]
    _, _, _, T6, _, p6, w = seiliger_cycle(p1, T1, q, X_cv, X_ct, c0)
    Q_brake = P / (2.0 * math.pi * n)
    Q_ind = m1 * w * c0.torque_per_work
    out["Q_loss_nom_Nm"] = _e(Q_ind - Q_brake, "N m", "eq. 3.10 at the nominal point: indicated minus brake torque")
    if Q_ind <= Q_brake:
        raise ValueError(f"{name}: indicated torque {Q_ind:.0f} N m below brake torque {Q_brake:.0f} N m")

    s_sl = v["s_sl_nom"]
    cp_a, cp_g, nb = v["c_p_a_J_per_kgK"], v["c_p_g_J_per_kgK"], v["n_bld"]
    psi2, psi3 = cp_a * s_sl * m1, cp_g * (x1 + m1)
    mdot = ((1.0 + s_sl) * m1 + x1) * n * v["n_cylinders"] / v["revs_per_cycle"]
    chi = cp_g / cp_a
    dfac = 1.0 + x1 / ((1.0 + s_sl) * m1)
    eta_tc = v["a_eta_per_Pa2"] * p1**2 + v["b_eta_per_Pa"] * p1 + v["c_eta"]

    def T_in(pd: float) -> float:
        return (psi2 * T1 + psi3 * T6 * (1.0 / nb + (nb - 1.0) / nb * pd / p6)) / (psi2 + psi3)

    def balance(pd: float) -> float:
        Pi = (v["p_ex_Pa"] / pd) ** c0.pi_exp
        base = 1.0 + chi * dfac * eta_tc * T_in(pd) / v["T_amb_K"] * (1.0 - Pi)
        return v["p_amb_Pa"] * base ** (ka / (ka - 1.0)) - p1

    pd = brentq(balance, v["p_ex_Pa"] * (1.0 + 1e-9), 50.0 * p1, xtol=1e-9, rtol=1e-14)
    if pd >= p1:
        raise ValueError(f"{name}: receiver pressure {pd:.0f} Pa above charge pressure: no scavenging")
    Psi = scavenge_flow_function(pd / p1, c0)
    out["Psi_sc_nom"] = _e(
        Psi, "-", f"eq. 3.19 at the nominal receiver pressure p_d = {pd:.1f} Pa (root of eq. 3.31 = p1_nom)"
    )
    A = mdot * math.sqrt(v["R_g_J_per_kgK"] * T_in(pd) / (pd**2 - v["p_ex_Pa"] ** 2)) / v["alpha_z"]
    out["A_eff_m2"] = _e(A, "m2", "eq. 3.16 solved for the area at the nominal receiver pressure and flow")
    out.update(_turbocharger_speed_reference(name, v, mdot - x1 * n * v["n_cylinders"] / v["revs_per_cycle"]))
    return out


def _isentropic_head(T_in_K: float, pressure_ratio: float, cp: float = 1005.0, kappa: float = 1.4) -> float:
    """Isentropic compressor head c_p T (π^((κ-1)/κ) - 1) [J/kg]."""
    return cp * T_in_K * (pressure_ratio ** ((kappa - 1.0) / kappa) - 1.0)


def _turbocharger_speed_reference(name: str, v: dict[str, float], air_kg_s: float) -> dict[str, Entry]:
    """Rated turbocharger speed and its isentropic head (step 8 of the module docstring)."""
    cp, ka = v["c_p_a_J_per_kgK"], v["kappa_a"]
    if name == "wartsila-6l46":
        pt = PROTOCOL_TC_POINT
        dh = _isentropic_head(pt["T_inlet_K"], (pt["p_amb_Pa"] + pt["p_ca_gauge_Pa"]) / pt["p_amb_Pa"], cp, ka)
        return {
            "N_tc_nom_rpm": _e(pt["N_rpm"], "rpm", PROTOCOL_SRC),
            "dh_c_nom_J_per_kg": _e(
                dh, "J/kg", "isentropic compressor head c_p T (pi^((k-1)/k) - 1) at that reading: " + PROTOCOL_SRC
            ),
        }
    ref = derive_parameters("wartsila-6l46", INPUT_SETS["wartsila-6l46"])
    rv = {k: e["value"] for k, e in ref.items()}
    dh = _isentropic_head(v["T_amb_K"], v["p1_nom_Pa"] / v["p_amb_Pa"], cp, ka)
    air_ref = (1.0 + rv["s_sl_nom"]) * rv["m1_nom_kg"] * rv["n_nom_rev_s"] * rv["n_cylinders"] / rv["revs_per_cycle"]
    vol = air_kg_s / TURBOCHARGERS[name] * v["R_a_J_per_kgK"] * v["T_amb_K"] / v["p_amb_Pa"]
    vol_ref = air_ref / TURBOCHARGERS["wartsila-6l46"] * rv["R_a_J_per_kgK"] * rv["T_amb_K"] / rv["p_amb_Pa"]
    N = rv["N_tc_nom_rpm"] * math.sqrt(dh / rv["dh_c_nom_J_per_kg"]) * math.sqrt(vol_ref / vol)
    src = (
        f"similarity with wartsila-6l46 (same isentropic head coefficient, compressor diameter ~ sqrt(volume flow "
        f"per turbocharger), {TURBOCHARGERS[name]} turbochargers (choice)): an estimate, no speed record"
    )
    return {
        "N_tc_nom_rpm": _e(N, "rpm", src),
        "dh_c_nom_J_per_kg": _e(dh, "J/kg", "isentropic compressor head at the nominal point (p1_nom, p_amb, T_amb)"),
    }


def write_parameter_sets(directory: Path | None = None) -> list[Path]:
    """Derive every input set and write ``NAME.json`` files; returns their paths."""
    directory = directory or Path(__file__).parent.parent / "data" / "params"
    written = []
    for name, inputs in INPUT_SETS.items():
        entries = derive_parameters(name, inputs)
        order = [f.name for f in fields(EngineParams) if f.name not in ("name", "submodels")]
        doc = {
            "name": name,
            "description": _DESCRIPTIONS[name],
            "parameters": {k: entries[k] for k in order},
        }
        path = directory / f"{name}.json"
        path.write_text(json.dumps(doc, indent=1) + "\n")
        written.append(path)
    return written


_DESCRIPTIONS = {
    "thesis-12v28": "MAN 12V28/33D of the thesis (table 4.1), 5.4 MW at 16.71 rev/s; missing parameters derived "
    "from the nominal point and X_cv_nom calibrated to p_max = 188 bar (marine_fdi_env.engine.calibration).",
    "man-12v32-40": "MAN 12V32/40, 5.4 MW at 750 rpm: geometry, rating, SFC, charge pressure and ISO conditions from "
    "the project guide; everything else scaled from thesis-12v28 and re-derived at the nominal point.",
    "wartsila-6l46": "Wartsila 6L46, 5.89 MW at 500 rpm: geometry, rating, SFC and charge pressure from the Birka "
    "shop tests; everything else scaled from thesis-12v28 and re-derived at the nominal point.",
}
