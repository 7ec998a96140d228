"""The checkable claims of the thesis's chapter 6 (and its false-alarm claims in chapters 5-6) as data.

Every :class:`ThesisClaim` names the line of the extracted thesis text (:data:`THESIS_TEXT`, 1-based)
where its ``quote`` starts; the quote is a verbatim substring of that line (30-200 characters, the
LaTeX of the extraction kept as is, double spaces included), so a test can find it.  The catalogue
was read line by line from sections 6.1-6.5 (lines 1033-1448), the fault signature tables 6.5-6.8
(lines 1331-1368), and the false-alarm sentences of chapters 5-6.  Figures are missing from the
extraction: claims rest on the text and the figure captions only.

Ids and conventions
-------------------
* Sensor faults ``S<l>.<j>`` are the thesis's f_j^(l) on sensor S^(l){j}; modules ``M<l>.<q>`` are
  M^(l,q) (module M<l>.<q> checks sensor S<l>.<q>); process faults: ``valve_seizing`` f_u^(1),
  ``bore_damage`` f_{z,V1}^(2), ``turbine_seal_leak`` f_{x,tur}^(3), ``turbine_lubrication_loss``
  f_{z,Tsl}^(3), ``compressor_seal_leak`` f_{x,int}^(4), ``compressor_lubrication_loss`` f_{z,Tinl}^(4),
  ``intercooler_blockage`` f_{z,Tc}^(4) (tables 3.1, 6.4, 6.5-6.8, 6.10; the text also writes
  f_{fu}^(1), f_{z,sl}^(3), f_{T_sl}^(3), f_{z,int}^(4), f_{z,T_intl}^(4) for the same faults).
* Measured variables and their sensors (eq. 3.3-3.39, table 6.2): x^(1) S1.1/S1.2, z_1^(2) (cylinder
  pressure) S2.1/S2.2, z_2^(2) (cylinder temperature) S2.3/S2.4, z_3^(2) (torque) S2.5/S2.6, x^(3)
  S3.1/S3.2, z_1^(3) S3.3/S3.4, z_2^(3) S3.5, x^(4) S4.1/S4.2, z_1^(4) S4.3/S4.4, z_2^(4) S4.5/S4.6.
* Decision vectors D^(l) list module bits in the order M(l,1)..M(l,n_l).
* Times: ``value`` of ``event_time`` claims and ``time_s`` / ``onset_s`` are absolute simulation
  times [s]; delays of ``process_detection`` claims are seconds after the onset (``unit`` says which).
  The examples' event times are the interval boundaries of the text ("for 146.1 s <= t < 201.6 s,
  D^(2) = ..."); where a boundary equals a fault onset the thesis reports detection at the onset, to
  the text's resolution.
* Sets (``interim_set``, ``final_set``): ``value`` is the set as printed, a tuple of diagnoses, each a
  tuple of fault ids in the order printed.  ``and_combinations`` marks the thesis's "and any other
  combination of these faults"; ``reading`` gives the diagnoses the text means where the printed set
  needs interpretation; :func:`diagnoses` returns the set to compare with.

Kinds and counts (121 claims)
-----------------------------
======================  =====  ============================================================
kind                    count  what
======================  =====  ============================================================
sensor_detection        19     6.1: one per sensor fault, detection with noise and its size
process_detection       9      6.2: one per process fault (7) + 2 general statements (fault None)
process_signature       8      6.3: modules that detect each process fault (7) + no propagation
event_time              18     6.4.1-6.4.4: one per module that fires at a stated time
module_order            4      6.4.x: groups of modules in firing order
interim_set             4      6.4.x: the global diagnosis set the text states before the end
final_set               4      6.4.x: the global diagnosis set at the end of the run
kpi_spread              35     6.5.1: detection-time std below 0.003 s per (module, sensor fault)
min_detectable          7      6.5.2: table 6.10
false_alarms            13     5.3.2, 6.1, 6.2, 6.4.x: every "no false alarm" statement
======================  =====  ============================================================

``process_signature`` and ``interim_set`` extend the brief's kinds: both are checkable statements of
chapter 6 (line 1349; the diagnosis sets of lines 1382-1410) that no other kind covers.

Ambiguities
-----------
* "X % of the maximum measurement" (6.1).  The noise rule (line 1033, 1220) says the noise bound is
  3 % of the maximum amplitude of the noiseless measurement, so one reading of X % is X/3 times the
  table 6.3 noise bound; another is X % of the sensor's full-load value.  ``size`` gives the
  noise-rule number and the table 6.3 magnitude (with the % of the maximum it is by the noise rule);
  the full-load numbers are not computed here.  By the noise rule the table 6.3 magnitudes are
  9.7-28.5 % of the maximum, not the 5-10 % the text states (line 1220): the two cannot both hold.
* 6.1 shows one residual per measured variable and does not say which of a redundant pair was
  faulted; the claim is catalogued for both sensors of the pair (``note`` says so).
* 6.5.1 (line 1420) claims std < 0.003 s "for permanent, abrupt, offset sensor faults that were
  detected by the monitoring modules"; fig. 6.35 (one value per module) is missing.  The pairs are the
  '1' cells of the sensor-fault columns of tables 6.5-6.8 (35; '*' cells, "may be affected", are
  left out: with them 82).  Eq. 6.1-6.2 define one sigma^(l,q) per module with "T_f^(l,q) the
  occurrence time of the fault that affects each sensor", which suggests the narrower reading of one
  pair per module, its own sensor (the 19 claims with ``fault[1:] == module[1:]``).  The 62 pairs of
  ``docs/diagnosis_results.md``'s KPI 6.5.1 table are the modules our reference diagnoser was seen to
  fire, not a thesis number.
* Table 6.10's valve fault is "phi_u = 1.85x10^-2 %"; table 6.4's "phi_u = 25 %" is used as the
  fraction 0.25 (``PROCESS_FAULT_DEFAULTS``), so a consistent reading of 1.85e-2 % is the fraction
  1.85e-4; the fraction 1.85e-2 (as ``studies.diagnosis.kpis`` uses it) matches the thesis's own
  6.2 detection (25 % detected about 10 s after onset with kappa = 0.01 1/s, i.e. at ~2.4 % of fuel)
  and is the more plausible one.  ``value`` keeps the printed 1.85e-2 and unit "%".
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from pathlib import Path

__all__ = [
    "ThesisClaim",
    "CLAIMS",
    "KINDS",
    "COUNTS",
    "THESIS_TEXT",
    "TABLE_6_3",
    "TABLE_ONE_CELLS",
    "NOISE_SHARE_PCT",
    "claims",
    "claim",
    "diagnoses",
]

THESIS_TEXT = Path(__file__).resolve().parents[3] / "shared" / "seed" / "000_57fb347d9df6a23d.txt"

KINDS: tuple[str, ...] = (
    "sensor_detection",
    "process_detection",
    "process_signature",
    "event_time",
    "module_order",
    "interim_set",
    "final_set",
    "kpi_spread",
    "min_detectable",
    "false_alarms",
)
COUNTS: dict[str, int] = {
    "sensor_detection": 19,
    "process_detection": 9,
    "process_signature": 8,
    "event_time": 18,
    "module_order": 4,
    "interim_set": 4,
    "final_set": 4,
    "kpi_spread": 35,
    "min_detectable": 7,
    "false_alarms": 13,
}


@dataclass(frozen=True)
class ThesisClaim:
    """One checkable statement of the thesis, where it is and what it says (see module docstring)."""

    id: str
    section: str
    line: int
    quote: str
    kind: str
    fault: str | None
    module: str | None
    scenario: str | None
    value: float | str | tuple | None
    unit: str
    size: str
    size_pct_of_max: float | None
    note: str = ""
    thesis_symbol: str = ""  # the thesis's notation of the fault (or faults) the claim is about
    onset_s: float | None = None  # onset of that fault in the run the claim describes [s, absolute]
    time_s: float | None = None  # sets: time from which the set holds [s, absolute]
    size_pct_no_noise: float | None = None  # sensor claims: % of the maximum measurement without noise
    and_combinations: bool = False  # sets: the thesis adds "and any other combination of these faults"
    reading: tuple | None = None  # sets: the diagnoses meant, where the printed set needs interpretation


# ----------------------------------------------------------------------------- 6.1 sensor faults
# table 6.3 (lines 1188-1206): sensor -> (noise bound, fault magnitude, unit)
TABLE_6_3: dict[str, tuple[float, float, str]] = {
    "S1.1": (4.5e-5, 1.8e-4, "kg"),
    "S1.2": (4.5e-5, 1.8e-4, "kg"),
    "S2.1": (2e4, 9e4, "Pa"),
    "S2.2": (2e4, 9e4, "Pa"),
    "S2.3": (17.0, 55.0, "K"),
    "S2.4": (17.0, 55.0, "K"),
    "S2.5": (0.75e3, 7.125e3, "Nm"),
    "S2.6": (0.75e3, 7.125e3, "Nm"),
    "S3.1": (0.99e3, 5e3, "Pa"),
    "S3.2": (0.99e3, 5e3, "Pa"),
    "S3.3": (8.0, 48.0, "K"),
    "S3.4": (8.0, 48.0, "K"),
    "S3.5": (6.0, 25.0, "K"),
    "S4.1": (5.5e3, 5e4, "Pa"),
    "S4.2": (5.5e3, 5e4, "Pa"),
    "S4.3": (5.0, 22.0, "K"),
    "S4.4": (5.0, 22.0, "K"),
    "S4.5": (5.0, 25.0, "K"),
    "S4.6": (5.0, 25.0, "K"),
}
NOISE_SHARE_PCT = 3.0  # noise bound = 3 % of the maximum noiseless amplitude (lines 1033, 1220)


def _sensor_size(sensor: str, pct: float, no_noise: str) -> str:
    bound, magnitude, unit = TABLE_6_3[sensor]
    return (
        f"{pct:g} % of the maximum measurement with noise (no noise: {no_noise}); noise-rule reading "
        f"{pct:g}/3 x {bound:g} {unit} = {pct / NOISE_SHARE_PCT * bound:.4g} {unit}; table 6.3 magnitude "
        f"{magnitude:g} {unit} (= {NOISE_SHARE_PCT * magnitude / bound:.3g} % of the maximum by the noise rule)"
    )


def _sensor_claims(
    sensors: tuple[str, ...],
    variable: str,
    figures: str,
    onset_s: float,
    line: int,
    quote: str,
    value: str,
    pct: float,
    no_noise_pct: float,
    no_noise: str,
    note: str = "",
) -> tuple[ThesisClaim, ...]:
    pair = (
        f"The text covers the redundant pair {'/'.join(sensors)} jointly (one residual of {variable}; which "
        "sensor was faulted is not said): one claim per sensor. "
        if len(sensors) > 1
        else f"Single sensor of {variable}. "
    )
    return tuple(
        ThesisClaim(
            id=f"6.1/{s}",
            section="6.1",
            line=line,
            quote=quote,
            kind="sensor_detection",
            fault=s,
            module=None,
            scenario=None,
            value=value,
            unit="-",
            size=_sensor_size(s, pct, no_noise),
            size_pct_of_max=pct,
            note=pair + f"Residual of {variable}, figs. {figures}; onset {onset_s:g} s (caption). " + note,
            thesis_symbol=f"f_{s[3]}^({s[1]})",
            onset_s=onset_s,
            size_pct_no_noise=no_noise_pct,
        )
        for s in sensors
    )


_SENSOR_CLAIMS: tuple[ThesisClaim, ...] = (
    *_sensor_claims(
        ("S1.1", "S1.2"),
        "x^(1)",
        "6.1 (no noise) and 6.2 (noise)",
        25.0,
        1105,
        "The sensor fault amplitude was set equal to 6% of the maximum measurement indicated by the sensor, "
        "due to the noise, and it was detected almost immediately after it appears",
        "almost immediately",
        6.0,
        5.0,
        "'can be set lower than 5%', detected almost immediately",
        "Without noise the text gives only an upper bound (lower than 5 %); size_pct_no_noise holds 5.",
    ),
    *_sensor_claims(
        ("S2.1", "S2.2"),
        "z_1^(2) (cylinder pressure)",
        "6.3 and 6.4",
        55.0,
        1107,
        "the sensor fault amplitude was set to 5% of the maximum measurement indicated by the sensor and it was "
        "detected almost immediately after it appears, as can be seen in fig. 6.4",
        "almost immediately",
        5.0,
        2.0,
        "2 %, detected almost immediately",
    ),
    *_sensor_claims(
        ("S2.3", "S2.4"),
        "z_2^(2) (cylinder temperature)",
        "6.5 and 6.6",
        85.0,
        1129,
        "The sensor fault amplitude was set to 5.5% of the maximum measurement indicated by the sensor and was "
        "detected instantly after it appears.",
        "instantly",
        5.5,
        4.0,
        "4 %, detected almost immediately",
        "The with-noise statement says 'instantly', the others 'almost immediately'.",
    ),
    *_sensor_claims(
        ("S2.5", "S2.6"),
        "z_3^(2) (torque)",
        "6.7 and 6.8",
        115.0,
        1131,
        "the sensor fault amplitude was set to 10% of the maximum measurement indicated by the sensor and it was "
        "detected almost immediately after it appears",
        "almost immediately",
        10.0,
        5.0,
        "5 %, detected almost immediately",
        "Line 1131 names the variable z_3^(2) in 'figures 6.7 and 6.8'; z_3^(2) is the shaft torque (eq. 3.7).",
    ),
    *_sensor_claims(
        ("S3.1", "S3.2"),
        "x^(3) (exhaust receiver pressure)",
        "6.9 and 6.10",
        145.0,
        1155,
        "The sensor fault amplitude was set equal to 5% of the maximum measurement indicated by the sensor, due "
        "to the noise, and was detected almost immediately after it appears, as can be seen in fig. 6.10.",
        "almost immediately",
        5.0,
        4.0,
        "4 % (line 1133), detected almost immediately",
        "The paragraph starts on line 1133 (no noise) and continues on line 1155 (noise) after the captions.",
    ),
    *_sensor_claims(
        ("S3.3", "S3.4"),
        "z_1^(3) (turbine inlet temperature)",
        "6.11 and 6.12",
        175.0,
        1157,
        "the sensor fault amplitude was set to 7.5% of the maximum measurement indicated by the sensor and was "
        "detected almost immediately after it appears, as can be seen in fig. 6.12.",
        "almost immediately",
        7.5,
        5.0,
        "5 %, detected almost immediately",
        "Same onset (175 s) as the S3.4 fault of example 6.4.1.",
    ),
    *_sensor_claims(
        ("S3.5",),
        "z_2^(3) (turbine outlet temperature)",
        "6.13 and 6.14",
        205.0,
        1159,
        "the sensor fault amplitude was set to 5% of the maximum measurement indicated by the sensor and was "
        "detected almost immediately after it appears, as can be seen in fig. 6.14",
        "almost immediately",
        5.0,
        2.5,
        "2.5 %, detected almost immediately",
    ),
    *_sensor_claims(
        ("S4.1", "S4.2"),
        "x^(4) (charge-air pressure)",
        "6.15 and 6.16",
        235.0,
        1181,
        "The sensor fault amplitude was set equal to 10% of the maximum measurement indicated by the sensor, due "
        "to the noise, and was detected almost immediately after it appears",
        "almost immediately",
        10.0,
        5.0,
        "5 %, detected almost immediately",
        "Same onset (235 s) as the S4.2 fault of example 6.4.1.",
    ),
    *_sensor_claims(
        ("S4.3", "S4.4"),
        "z_1^(4) (air temperature before the intercooler, eq. 3.30)",
        "6.17 and 6.18",
        265.0,
        1183,
        "the sensor fault amplitude was set to 7% of the maximum measurement indicated by the sensor and was "
        "detected almost immediately after it appears, as can be seen in fig. 6.18",
        "almost immediately",
        7.0,
        4.5,
        "4.5 %, detected almost immediately",
    ),
    *_sensor_claims(
        ("S4.5", "S4.6"),
        "z_2^(4) (air temperature after the intercooler, eq. 3.30)",
        "6.19 (onset 275 s) and 6.20 (onset 280 s)",
        280.0,
        1218,
        "the sensor fault amplitude was set to 8% of the maximum measurement indicated by the sensor and was "
        "detected almost immediately after it appears, as can be seen in fig. 6.20",
        "almost immediately",
        8.0,
        5.0,
        "5 %, detected almost immediately",
        "The two captions differ: 275 s without noise (fig. 6.19), 280 s with noise (fig. 6.20); onset_s is the "
        "with-noise one.",
    ),
)


# ----------------------------------------------------------------------------- 6.2 process faults
def _t64(fault: str) -> str:
    return {
        "valve_seizing": "table 6.4: t1 = 20 s, kappa = 1e-2 1/s, phi_u = 25 % (PROCESS_FAULT_DEFAULTS: 0.25)",
        "bore_damage": "table 6.4: t1 = 15 s, kappa = 1e-5 1/s, R = 3e-3 m3/s",
        "turbine_seal_leak": "table 6.4: t1 = 15 s, kappa = 2e-5 1/s, R = 3.5e-4 Hz",
        "turbine_lubrication_loss": "table 6.4: t1 = 30 s, kappa = 1e3 1/s, R = 1.25 K/s",
        "compressor_seal_leak": "table 6.4: t1 = 30 s, kappa = 1e-4 1/s, R = 5e-2 Hz",
        "compressor_lubrication_loss": "table 6.4: t1 = 30 s, kappa = 1e3 1/s, R = 2.5 K/s",
        "intercooler_blockage": "table 6.4: t1 = 30 s, kappa = 1e-3 1/s, R = 2 K/s",
    }[fault]


def _process(
    fault: str, symbol: str, line: int, quote: str, value, unit: str, onset_s: float, note: str
) -> ThesisClaim:
    return ThesisClaim(
        id=f"6.2/{fault}",
        section="6.2",
        line=line,
        quote=quote,
        kind="process_detection",
        fault=fault,
        module=None,
        scenario=None,
        value=value,
        unit=unit,
        size=_t64(fault) + " (with noise; the text does not restate the sizes)",
        size_pct_of_max=None,
        note=note,
        thesis_symbol=symbol,
        onset_s=onset_s,
    )


_PROCESS_CLAIMS: tuple[ThesisClaim, ...] = (
    _process(
        "valve_seizing",
        "f_u^(1) (written f_{fu}^(1) on line 1236)",
        1236,
        "the fault was detected almost 10 seconds later of its initiation, as a result of the higher adaptive "
        "threshold imposed due to sensor noise",
        10.0,
        "s after onset",
        20.0,
        "With noise (fig. 6.22); 'almost 10 seconds': at most about 10 s.  No time is stated without noise "
        "(fig. 6.21).  The onset is not in the text; table 6.4 gives t1 = 20 s.  Example 6.4.2 (onset 200 s): "
        "M1.1 and M1.2 fire at 207.1 s, 7.1 s after the onset.",
    ),
    _process(
        "bore_damage",
        "f_{z,V1}^(2)",
        1248,
        "The fault was initiated at 15sec in both cases and it was detected at a far later stage as can be seen "
        "in the case where the sensor noise is present.",
        "far later stage",
        "-",
        15.0,
        "With noise (fig. 6.24): 'at a far later stage due to the higher threshold values' (line 1250); without "
        "noise (fig. 6.23): 'almost immediately after its activation'.  No number.  Example 6.4.2 (onset 5 s): "
        "first modules M2.3, M2.4 at 146.1 s, i.e. 141.1 s after the onset.",
    ),
    _process(
        "turbine_seal_leak",
        "f_{x,tur}^(3)",
        1262,
        "In both cases, this process fault was detected successfully and in a relatively short time after it occurred.",
        "relatively short time",
        "-",
        15.0,
        "Without noise (fig. 6.25) 'almost immediately'; with noise (fig. 6.26) 'it takes longer to detect'.  "
        "No number; onset 15 s (line 1262, table 6.4).",
    ),
    _process(
        "turbine_lubrication_loss",
        "f_{z,Tsl}^(3)",
        1274,
        "Both in the absence and presence of sensor noise, detection of the fault happens around the middle of "
        "the simulation time",
        "around the middle of the simulation time",
        "-",
        30.0,
        "Read as about 150 s of the 300 s run, i.e. about 120 s after the 30 s onset; with noise (fig. 6.28) "
        "earlier than without (fig. 6.27).  Example 6.4.4 (onset 30 s): M3.3, M3.4 at 104.6 s, 74.6 s after "
        "the onset.",
    ),
    _process(
        "compressor_seal_leak",
        "f_{x,int}^(4)",
        1286,
        "the sensor noise presence leads to a higher adaptive threshold, to avoid false alarms, and as a result, "
        "the fault detection happens at a far later stage.",
        "far later stage",
        "-",
        30.0,
        "With noise (fig. 6.30).  Without noise (fig. 6.29): 'detected a very short time after its activation'.  "
        "No number.  Example 6.4.3 (onset 30 s): M4.1, M4.2 at 156.8 s, 126.8 s after the onset.",
    ),
    _process(
        "compressor_lubrication_loss",
        "f_{z,Tinl}^(4)",
        1298,
        "The fault was activated at 30 seconds and was detected shortly after that, both in the absence and "
        "presence of sensor noise",
        "shortly after",
        "-",
        30.0,
        "Figs. 6.31 (no noise) and 6.32 (noise); no number.",
    ),
    _process(
        "intercooler_blockage",
        "f_{z,Tc}^(4)",
        1300,
        "This process fault was initiated at 30 seconds and it was detected about 15 seconds after its "
        "initialization in the presence of sensor noise.",
        15.0,
        "s after onset",
        30.0,
        "With noise (fig. 6.34); no time is stated without noise (fig. 6.33).",
    ),
    ThesisClaim(
        id="6.2/general/most-immediate",
        section="6.2",
        line=1224,
        quote="Most process faults were detected almost immediately, while a few are detected at a later stage of "
        "the simulation.",
        kind="process_detection",
        fault=None,
        module=None,
        scenario=None,
        value="most almost immediately, a few at a later stage",
        unit="-",
        size="table 6.4",
        size_pct_of_max=None,
        note="Does not say with or without noise; contradicts line 1323 for the runs with noise.",
    ),
    ThesisClaim(
        id="6.2/general/far-later-with-noise",
        section="6.2",
        line=1323,
        quote="Regarding the detection of process faults in the presence of sensor noise, in general, the faults "
        "are detected at a far later stage than the time of their occurrence.",
        kind="process_detection",
        fault=None,
        module=None,
        scenario=None,
        value="far later stage (with noise)",
        unit="-",
        size="table 6.4 (with noise)",
        size_pct_of_max=None,
        note="Repeated in 7.2.1 (line 1479).  Contradicts line 1224 ('most ... almost immediately') unless that "
        "one means the runs without noise.",
    ),
)


# ----------------------------------------------------------------------------- 6.3 process-fault signatures
def _signature(fault: str, symbol: str, quote: str, modules: tuple[str, ...], note: str = "") -> ThesisClaim:
    return ThesisClaim(
        id=f"6.3/{fault}",
        section="6.3",
        line=1349,
        quote=quote,
        kind="process_signature",
        fault=fault,
        module=None,
        scenario=None,
        value=modules,
        unit="-",
        size="not stated (tables 6.5-6.8 are structural, 'in the presence of sensor noise')",
        size_pct_of_max=None,
        note=note,
        thesis_symbol=symbol,
    )


_SIGNATURE_CLAIMS: tuple[ThesisClaim, ...] = (
    _signature(
        "valve_seizing",
        "f_u^(1)",
        "the process fault regarding fuel injection valve seizing is detected by both monitoring modules in of "
        "the agent",
        ("M1.1", "M1.2"),
        "Table 6.5 column f_u^(1): 1, 1.",
    ),
    _signature(
        "bore_damage",
        "f_{z,V1}^(2)",
        r"the process fault  $f_{z,V_1}^{(2)}$  regarding bore damage, is detected by all the modules of  "
        r"$\mathcal{M}^{(2)}$",
        ("M2.1", "M2.2", "M2.3", "M2.4", "M2.5", "M2.6"),
        "Table 6.6 column f_{z,V1}^(2) is 1 for M2.1-M2.4 and '*' (may be affected) for M2.5, M2.6; in example "
        "6.4.2 only M2.1-M2.4 fire.",
    ),
    _signature(
        "turbine_seal_leak",
        "f_{x,tur}^(3)",
        r"the process faults  $f_{x,tur}^{(3)}$  and  $f_{z,sl}^{(3)}$  are detected by modules  "
        r"$\mathcal{M}^{(3,1)}$ ,  $\mathcal{M}^{(3,2)}$",
        ("M3.1", "M3.2"),
        "'respectively': f_{x,tur} by M3.1, M3.2 (table 6.7: 1, 1).",
    ),
    _signature(
        "turbine_lubrication_loss",
        "f_{z,Tsl}^(3) (written f_{z,sl}^(3) on line 1349)",
        r"the process faults  $f_{x,tur}^{(3)}$  and  $f_{z,sl}^{(3)}$  are detected by modules  "
        r"$\mathcal{M}^{(3,1)}$ ,  $\mathcal{M}^{(3,2)}$",
        ("M3.3", "M3.4"),
        "'respectively': f_{z,sl} (= f_{z,Tsl}) by M3.3, M3.4 (table 6.7: 1, 1); the quote's continuation "
        "names M(3,3), M(3,4).",
    ),
    _signature(
        "compressor_seal_leak",
        "f_{x,int}^(4)",
        r"the occurrence of  $f_{x,int}^{(4)}$  is detected by  $\mathcal{M}^{(4,1)}$ ,  $\mathcal{M}^{(4,2)}$",
        ("M4.1", "M4.2"),
        "Table 6.8: 1, 1.",
    ),
    _signature(
        "compressor_lubrication_loss",
        "f_{z,Tinl}^(4) (written f_{z,int}^(4) on line 1349)",
        r"the occurrence of  $f_{z,int}^{(4)}$  is detected by  $\mathcal{M}^{(4,3)}$ ,  $\mathcal{M}^{(4,4)}$",
        ("M4.3", "M4.4"),
        "f_{z,int}^(4) here is f_{z,Tinl}^(4) (table 6.8 column f_{z,Tint}: M4.3, M4.4).",
    ),
    _signature(
        "intercooler_blockage",
        "f_{z,Tc}^(4)",
        r"the occurrence of  $f_{z,T_c}^{(4)}$  is detected by  $\mathcal{M}^{(4,5)}$ ,  $\mathcal{M}^{(4,6)}$",
        ("M4.5", "M4.6"),
        "Table 6.8: 1, 1.",
    ),
    ThesisClaim(
        id="6.3/no-propagation",
        section="6.3",
        line=1347,
        quote="the process faults that affect a system, cannot be detected by the monitoring agents of neighboring "
        "systems.",
        kind="process_signature",
        fault=None,
        module=None,
        scenario=None,
        value="no process fault is detected by another agent's modules",
        unit="-",
        size="any",
        size_pct_of_max=None,
        note="Also line 1009 (5.3.3) and line 1349 ('these faults do not propagate from one system to another').  "
        "src/marine_fdi_env/diagnosis/modules.py argues that through the engine speed they do.",
    ),
)


# ----------------------------------------------------------------------------- 6.4 examples
_EX_SIZE = "not stated in 6.4 (the scenario uses the table 6.3 / 6.4 defaults)"


def _event(
    example: str,
    module: str,
    time_s: float,
    fault: str,
    onset_s: float,
    line: int,
    quote: str,
    note: str,
) -> ThesisClaim:
    return ThesisClaim(
        id=f"{example}/event/{module}",
        section=example,
        line=line,
        quote=quote,
        kind="event_time",
        fault=fault,
        module=module,
        scenario=f"thesis-{example}",
        value=time_s,
        unit="s",
        size=_EX_SIZE,
        size_pct_of_max=None,
        note=note + f" Fires {time_s - onset_s:.1f} s after the {fault} onset at {onset_s:g} s.",
        onset_s=onset_s,
    )


_Q641_175 = (
    r"For  $175sec \leq t < 235sec$  the agents  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  "
    r"$\mathcal{M}^{(4)}$  produce the decision vectors"
)
_Q641_235 = (
    r"For  $t > 235sec$  the output of monitoring agents  $\mathcal{M}^{(2)}$  and  $\mathcal{M}^{(4)}$  are  "
    r"$D^{(2)}(t) = [0\ 1\ 0\ 1\ 0\ 0]^T$"
)
_Q642_146 = (
    r"For  $146.1sec \leq t < 201.6sec$ , monitoring agent  $\mathcal{M}^{(2)}$  produces the decision vector  "
    r"$D^{(2)}(t) = [0 \ 0 \ 1 \ 1 \ 0 \ 0]^T$"
)
_Q642_201 = (
    r"For  $201.6sec \leq t < 207.1sec$ , monitoring agent  $\mathcal{M}^{(2)}$  changes its decision vector "
    r"once more to  $D^{(2)}(t) = [1 \ 1 \ 1 \ 1 \ 0 \ 0]^T$"
)
_Q642_207 = (
    r"for  $t > 207.1sec$  the agents  $\mathcal{M}^{(1)}$ ,  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  "
    r"$\mathcal{M}^{(4)}$  produce the decision vectors  $D^{(1)}(t) = [1 \ 1]^T$"
)
_Q643_20 = (
    r"For  $20sec \leq t < 156.8sec$  the agents  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  "
    r"$\mathcal{M}^{(4)}$  produce the decision vectors  $D^{(2)}(t) = [0 \ 1 \ 0 \ 0 \ 0 \ 0]^T$"
)
_Q643_156 = (
    r"$t > 156.8sec$  the agents  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  $\mathcal{M}^{(4)}$  "
    r"produce the decision vectors"
)
_Q644_15 = (
    r"For  $15sec \leq t < 104.6sec$  the agents  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  "
    r"$\mathcal{M}^{(4)}$  produce the decision vectors"
)
_Q644_104 = (
    r"for  $t > 104.6sec$  the agents  $\mathcal{M}^{(2)}$ ,  $\mathcal{M}^{(3)}$  and  $\mathcal{M}^{(4)}$  "
    r"produce the decision vectors"
)

_N641_175 = "D^(3) = [0 0 0 1 1] (M3.4, M3.5 set), D^(2) and D^(4) zero, from 175 s."
_N641_235 = (
    "From 235 s: D^(2) = [0 1 0 1 0 0] (M2.2, M2.4), D^(3) = [0 0 0 1 1] unchanged, D^(4) = [0 1 0 0 0 0] (M4.2)."
)
_N642_146 = "D^(2) = [0 0 1 1 0 0] (M2.3, M2.4) from 146.1 s; the other agents' vectors are empty."
_N642_201 = (
    "D^(2) = [1 1 1 1 0 0] (M2.1, M2.2 added) from 201.6 s, 1.6 s after the valve_seizing onset (200 s); the "
    "thesis keeps D_s^(2) = {f_{z,V1}^(2)} and names no other cause, so the firing is attributed to bore_damage "
    "(table 6.6 has no f_u column; by 5.3.3 process faults do not propagate)."
)
_N642_207 = "D^(1) = [1 1] (M1.1, M1.2) after 207.1 s; D^(2) = [1 1 1 1 0 0], D^(3), D^(4) zero."
_N643_20 = "D^(2) = [0 1 0 0 0 0] (M2.2) from 20 s; D^(3), D^(4) zero (D^(4) printed with 5 entries, a typo)."
_N643_156 = "D^(4) = [1 1 0 0 0 0] (M4.1, M4.2) after 156.8 s; D^(2) = [0 1 0 0 0 0] unchanged, D^(3) zero."
_N644_15 = "D^(3) = [0 1 0 0 0] (M3.2), D^(4) = [0 1 0 0 0 0] (M4.2) from 15 s; D^(2) zero."
_N644_104 = "D^(3) = [0 1 1 1 0] (M3.3, M3.4 added) after 104.6 s; D^(4) = [0 1 0 0 0 0] unchanged, D^(2) zero."

_EVENT_CLAIMS: tuple[ThesisClaim, ...] = (
    _event("6.4.1", "M3.4", 175.0, "S3.4", 175.0, 1382, _Q641_175, _N641_175),
    _event("6.4.1", "M3.5", 175.0, "S3.4", 175.0, 1382, _Q641_175, _N641_175),
    _event("6.4.1", "M2.2", 235.0, "S4.2", 235.0, 1382, _Q641_235, _N641_235),
    _event("6.4.1", "M2.4", 235.0, "S4.2", 235.0, 1382, _Q641_235, _N641_235),
    _event("6.4.1", "M4.2", 235.0, "S4.2", 235.0, 1382, _Q641_235, _N641_235),
    _event("6.4.2", "M2.3", 146.1, "bore_damage", 5.0, 1392, _Q642_146, _N642_146),
    _event("6.4.2", "M2.4", 146.1, "bore_damage", 5.0, 1392, _Q642_146, _N642_146),
    _event("6.4.2", "M2.1", 201.6, "bore_damage", 5.0, 1392, _Q642_201, _N642_201),
    _event("6.4.2", "M2.2", 201.6, "bore_damage", 5.0, 1392, _Q642_201, _N642_201),
    _event("6.4.2", "M1.1", 207.1, "valve_seizing", 200.0, 1392, _Q642_207, _N642_207),
    _event("6.4.2", "M1.2", 207.1, "valve_seizing", 200.0, 1392, _Q642_207, _N642_207),
    _event("6.4.3", "M2.2", 20.0, "S2.2", 20.0, 1400, _Q643_20, _N643_20),
    _event("6.4.3", "M4.1", 156.8, "compressor_seal_leak", 30.0, 1402, _Q643_156, _N643_156),
    _event("6.4.3", "M4.2", 156.8, "compressor_seal_leak", 30.0, 1402, _Q643_156, _N643_156),
    _event("6.4.4", "M3.2", 15.0, "S3.2", 15.0, 1410, _Q644_15, _N644_15),
    _event("6.4.4", "M4.2", 15.0, "S3.2", 15.0, 1410, _Q644_15, _N644_15),
    _event("6.4.4", "M3.3", 104.6, "turbine_lubrication_loss", 30.0, 1410, _Q644_104, _N644_104),
    _event("6.4.4", "M3.4", 104.6, "turbine_lubrication_loss", 30.0, 1410, _Q644_104, _N644_104),
)

_ORDER_NOTE = (
    " Groups in firing order; modules of one group fire at the same stated time; modules not listed are 0 in "
    "every decision vector the text prints (never fire)."
)
_ORDER_CLAIMS: tuple[ThesisClaim, ...] = tuple(
    ThesisClaim(
        id=f"{ex}/order",
        section=ex,
        line=line,
        quote=quote,
        kind="module_order",
        fault=None,
        module=None,
        scenario=f"thesis-{ex}",
        value=groups,
        unit="-",
        size=_EX_SIZE,
        size_pct_of_max=None,
        note=note + _ORDER_NOTE,
        thesis_symbol=symbols,
    )
    for ex, line, quote, groups, note, symbols in (
        (
            "6.4.1",
            1382,
            _Q641_235,
            (("M3.4", "M3.5"), ("M2.2", "M2.4", "M4.2")),
            "175 s: M3.4, M3.5 (S3.4); 235 s: M2.2, M2.4, M4.2 (S4.2).  M2.6, M3.2 and M4.6, marked '*' for "
            "these faults in tables 6.6-6.8, stay 0.",
            "f_4^(3) at 175 s, f_2^(4) at 235 s",
        ),
        (
            "6.4.2",
            1392,
            _Q642_201,
            (("M2.3", "M2.4"), ("M2.1", "M2.2"), ("M1.1", "M1.2")),
            "146.1 s: M2.3, M2.4; 201.6 s: M2.1, M2.2; 207.1 s: M1.1, M1.2.  M2.5, M2.6 ('*' for f_{z,V1}) never "
            "fire.  The appendix figures A.11-A.20 show only the even modules.",
            "f_{z,V1}^(2) at 5 s, f_u^(1) at 200 s",
        ),
        (
            "6.4.3",
            1400,
            _Q643_20,
            (("M2.2",), ("M4.1", "M4.2")),
            "20 s: M2.2 (S2.2); 156.8 s: M4.1, M4.2 (compressor_seal_leak).",
            "f_2^(2) at 20 s, f_{x,int}^(4) at 30 s",
        ),
        (
            "6.4.4",
            1410,
            _Q644_15,
            (("M3.2", "M4.2"), ("M3.3", "M3.4")),
            "15 s: M3.2, M4.2 (S3.2); 104.6 s: M3.3, M3.4 (turbine_lubrication_loss).",
            "f_2^(3) at 15 s, f_{z,Tsl}^(3) at 30 s",
        ),
    )
)


def _set_claim(
    cid: str,
    kind: str,
    example: str,
    line: int,
    quote: str,
    value: tuple,
    time_s: float,
    note: str,
    symbols: str,
    and_combinations: bool = False,
    reading: tuple | None = None,
) -> ThesisClaim:
    return ThesisClaim(
        id=cid,
        section=example,
        line=line,
        quote=quote,
        kind=kind,
        fault=None,
        module=None,
        scenario=f"thesis-{example}",
        value=value,
        unit="-",
        size=_EX_SIZE,
        size_pct_of_max=None,
        note=note,
        thesis_symbol=symbols,
        time_s=time_s,
        and_combinations=and_combinations,
        reading=reading,
    )


_SET_CLAIMS: tuple[ThesisClaim, ...] = (
    _set_claim(
        "6.4.1/set@175",
        "interim_set",
        "6.4.1",
        1382,
        r"the global diagnosis set lies in the intersection  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi \cap "
        r"\mathcal{D}_s = \{f_4^{(3)}, f_5^{(3)}, \{f_4^{(3)}, f_5^{(3)}\}\}$",
        (("S3.4",), ("S3.5",), ("S3.4", "S3.5")),
        175.0,
        "For 175 s <= t < 235 s; equals the local set D_s^(3).  The singleton f_5^(3) does not match D^(3) = "
        "[0 0 0 1 1] by table 6.7 (its column is [0 0 0 0 1]); the thesis lists it anyway.",
        "{f_4^(3), f_5^(3), {f_4^(3), f_5^(3)}}",
    ),
    _set_claim(
        "6.4.1/final",
        "final_set",
        "6.4.1",
        1382,
        r"Thus the global diagnosis set is  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi \cap \mathcal{D}_s = "
        r"\{f_2^{(4)}, f_2^{(3)}, f_4^{(3)}, f_5^{(3)}\}$  and any other combination of these faults.",
        (("S4.2",), ("S3.2",), ("S3.4",), ("S3.5",)),
        235.0,
        "From 235 s to the end.  The injected pair {S3.4, S4.2} is only among the 'other combinations'.  The "
        "local set D_s^(4) also holds f_2^(1) (S1.2), dropped globally because D_chi = [0 1 1 1] clears agent 1.  "
        "kpis.scenario_checks counts 4 candidates (the printed singletons).",
        "{f_2^(4), f_2^(3), f_4^(3), f_5^(3)} and any other combination",
        and_combinations=True,
    ),
    _set_claim(
        "6.4.2/set@201.6",
        "interim_set",
        "6.4.2",
        1392,
        r"Therefore, the global diagnosis set lies in the intersection  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi "
        r"\cap \mathcal{D}_s^{(2)} = \{f_{z,V_1}^{(2)}\}$",
        (("bore_damage",),),
        201.6,
        "For 201.6 s <= t < 207.1 s.  No set is stated for 146.1-201.6 s (D^(2) = [0 0 1 1 0 0], which does not "
        "match table 6.6's f_{z,V1} column [1 1 1 1 * *] exactly).",
        "{f_{z,V1}^(2)}",
    ),
    _set_claim(
        "6.4.2/final",
        "final_set",
        "6.4.2",
        1392,
        r"Thus the global diagnosis set is  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi \cap \mathcal{D}_s = "
        r"\{f_u^{(1)}, f_{z,V_1}^{(2)}\}$",
        (("valve_seizing",), ("bore_damage",)),
        207.1,
        "From 207.1 s to the end.  Printed as two elements, the local sets D_s^(1) = {f_u} and D_s^(2) = "
        "{f_{z,V1}} side by side; the text says both process faults are isolated locally, so the meaning is "
        "the joint diagnosis {valve_seizing, bore_damage} (reading; kpis.scenario_checks counts 1 candidate).",
        "{f_u^(1), f_{z,V1}^(2)}",
        reading=(("valve_seizing", "bore_damage"),),
    ),
    _set_claim(
        "6.4.3/set@20",
        "interim_set",
        "6.4.3",
        1400,
        r"Therefore, the global diagnosis set lies in the intersection  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi "
        r"\cap \mathcal{D}_s^{(2)} = \{f_2^{(2)}\}$",
        (("S2.2",),),
        20.0,
        "For 20 s <= t < 156.8 s.",
        "{f_2^(2)}",
    ),
    _set_claim(
        "6.4.3/final",
        "final_set",
        "6.4.3",
        1402,
        r"The global diagnosis set is  $\mathcal{D}_s^\chi(t) = \mathcal{D}_s^\chi \cap \mathcal{D}_s = "
        r"\{f_{x,int}^{(4)}, f_2^{(2)}\}$",
        (("compressor_seal_leak",), ("S2.2",)),
        156.8,
        "From 156.8 s to the end.  The left-hand side is printed D_s^chi (a typo for D_s^G).  Two elements, the "
        "local sets D_s^(4) = {f_{x,int}} and D_s^(2) = {f_2^(2)}; meant as the joint diagnosis {S2.2, "
        "compressor_seal_leak} (reading; kpis.scenario_checks counts 1 candidate).",
        "{f_{x,int}^(4), f_2^(2)}",
        reading=(("S2.2", "compressor_seal_leak"),),
    ),
    _set_claim(
        "6.4.4/set@15",
        "interim_set",
        "6.4.4",
        1410,
        r"Hence, the global diagnosis set lies in the intersection  $\mathcal{D}_s^\chi(t) = \mathcal{D}_s^\chi "
        r"\cap \mathcal{D}_s = \{f_2^{(3)}, f_4^{(3)}, f_2^{(4)}, f_4^{(4)}\}$",
        (("S3.2",), ("S3.4",), ("S4.2",), ("S4.4",)),
        15.0,
        "For 15 s <= t < 104.6 s, 'and any other combination of these faults'.  Left-hand side printed D_s^chi "
        "(typo for D_s^G).  f_2^(1) (S1.2) of the local sets is dropped globally (D_chi = [0 0 1 1]).",
        "{f_2^(3), f_4^(3), f_2^(4), f_4^(4)} and any other combination",
        and_combinations=True,
    ),
    _set_claim(
        "6.4.4/final",
        "final_set",
        "6.4.4",
        1412,
        r"global diagnosis set is  $\mathcal{D}_s^G(t) = \mathcal{D}_s^\chi \cap \mathcal{D}_s = \{f_2^{(3)}, "
        r"f_4^{(3)}, f_2^{(4)}, \{f_2^{(3)}, f_4^{(3)}\}, \{f_4^{(3)}, f_2^{(4)}\},",
        (
            ("S3.2",),
            ("S3.4",),
            ("S4.2",),
            ("S3.2", "S3.4"),
            ("S3.4", "S4.2"),
            ("S3.2", "S4.2"),
            ("turbine_lubrication_loss", "S4.2"),
            ("turbine_lubrication_loss", "S3.2"),
            ("turbine_lubrication_loss", "S3.4"),
        ),
        104.6,
        "From 104.6 s to the end; the quote is cut at 200 characters, the set goes on with {f_2^(3), f_2^(4)}, "
        "{f_{T_sl}^(3), f_2^(4)}, {f_{T_sl}^(3), f_2^(3)}, {f_{T_sl}^(3), f_4^(3)} (f_{T_sl}^(3) = "
        "turbine_lubrication_loss).  9 elements, no 'other combinations'; the injected pair {S3.2, "
        "turbine_lubrication_loss} is one of them.  Locally D_s^(3) = {f_{T_sl}^(3)} alone although D^(3) = "
        "[0 1 1 1 0] also has M3.2 set, which the f_{z,Tsl} column [0 0 1 1 0] does not explain; the global set "
        "has no turbine_lubrication_loss singleton.",
        "{f_2^(3), f_4^(3), f_2^(4), {f_2^(3), f_4^(3)}, {f_4^(3), f_2^(4)}, {f_2^(3), f_2^(4)}, "
        "{f_Tsl^(3), f_2^(4)}, {f_Tsl^(3), f_2^(3)}, {f_Tsl^(3), f_4^(3)}}",
    ),
)


# ----------------------------------------------------------------------------- 6.5.1 detection-time spread
# The '1' cells of the sensor-fault columns of tables 6.5-6.8 (lines 1333-1368): fault -> modules.
TABLE_ONE_CELLS: dict[str, tuple[str, ...]] = {
    "S1.1": ("M1.1", "M2.1", "M2.3", "M3.1"),
    "S1.2": ("M1.2", "M2.2", "M2.4", "M3.2"),
    "S2.1": ("M2.1",),
    "S2.2": ("M2.2",),
    "S2.3": ("M2.3",),
    "S2.4": ("M2.4",),
    "S2.5": ("M2.5",),
    "S2.6": ("M2.6",),
    "S3.1": ("M3.1", "M4.1"),
    "S3.2": ("M3.2", "M4.2"),
    "S3.3": ("M3.3", "M3.5"),
    "S3.4": ("M3.4", "M3.5"),
    "S3.5": ("M3.5",),
    "S4.1": ("M2.1", "M2.3", "M4.1"),
    "S4.2": ("M2.2", "M2.4", "M4.2"),
    "S4.3": ("M2.3", "M4.3"),
    "S4.4": ("M2.4", "M4.4"),
    "S4.5": ("M4.5",),
    "S4.6": ("M4.6",),
}
_TABLE_OF_AGENT = {"1": "6.5", "2": "6.6", "3": "6.7", "4": "6.8"}
_Q651 = (
    r"since the standard deviation is maintained below  $\pm 0.003 \text{sec}$  for permanent, abrupt, "
    r"offset sensor faults that were detected by the monitoring modules."
)


def _spread(module: str, fault: str) -> ThesisClaim:
    own = module[1:] == fault[1:]
    return ThesisClaim(
        id=f"6.5.1/{module}/{fault}",
        section="6.5.1",
        line=1420,
        quote=_Q651,
        kind="kpi_spread",
        fault=fault,
        module=module,
        scenario=None,
        value=0.003,
        unit="s",
        size="not stated in 6.5.1 (presumably the permanent abrupt offsets of 6.1 / table 6.3); 100 runs with "
        "noise of the same amplitude and different realisations",
        size_pct_of_max=None,
        note=f"Table {_TABLE_OF_AGENT[module[1]]} cell ({module}, {fault}) = 1; "
        + (
            "the module's own sensor (also in the narrow reading, one sigma per module)."
            if own
            else "not the module's own sensor (only in the wide reading)."
        )
        + "  Std over the 100 runs of the delay T_D - T_f (eq. 6.1-6.2); fig. 6.35 is missing.",
        thesis_symbol=f"f_{fault[3]}^({fault[1]})",
    )


_SPREAD_CLAIMS: tuple[ThesisClaim, ...] = tuple(
    _spread(m, f) for f, modules in TABLE_ONE_CELLS.items() for m in modules
)


# ----------------------------------------------------------------------------- 6.5.2 table 6.10
def _min(fault: str, symbol: str, line: int, quote: str, value: float, unit: str, note: str) -> ThesisClaim:
    return ThesisClaim(
        id=f"6.10/{fault}",
        section="6.5.2",
        line=line,
        quote=quote,
        kind="min_detectable",
        fault=fault,
        module=None,
        scenario=None,
        value=value,
        unit=unit,
        size="the magnitude itself: lowest detected within the 300 s run (line 1448); kappa, onset and noise not "
        "restated (presumably table 6.4's kappa and onset, with noise)",
        size_pct_of_max=None,
        note=note,
        thesis_symbol=symbol,
    )


_MIN_CLAIMS: tuple[ThesisClaim, ...] = (
    _min(
        "turbine_seal_leak",
        "f_{x,tur}^(3)",
        1440,
        "$f_{x,tur}^{(3)}$\t$R_{x,tur}^{(3)} = 5x10^{-5}$\tHz",
        5e-5,
        "Hz",
        "R in 1/s; table 6.4 uses 3.5e-4.",
    ),
    _min(
        "turbine_lubrication_loss",
        "f_{z,Tsl}^(3)",
        1441,
        "$f_{z,Tsl}^{(3)}$\t$R_{z,Tsl}^{(3)} = 0.3$\tK/s",
        0.3,
        "K/s",
        "Table 6.4 uses 1.25.",
    ),
    _min(
        "compressor_seal_leak",
        "f_{x,int}^(4)",
        1442,
        "$f_{x,int}^{(4)}$\t$R_{x,int}^{(4)} = 78x10^{-4}$\tHz",
        78e-4,
        "Hz",
        "78e-4 = 7.8e-3; R in 1/s; table 6.4 uses 5e-2.",
    ),
    _min(
        "intercooler_blockage",
        "f_{z,Tc}^(4)",
        1443,
        "$f_{z,Tc}^{(4)}$\t$R_{z,Tc}^{(4)} = 3.75x10^{-2}$\tK/s",
        3.75e-2,
        "K/s",
        "Table 6.4 uses 2.",
    ),
    _min(
        "compressor_lubrication_loss",
        "f_{z,Tinl}^(4) (written f_{z,T_intl}^(4) in table 6.10)",
        1444,
        "$f_{z,T_{intl}}^{(4)}$\t$R_{z,T_{intl}}^{(4)} = 0.165$\tK/s",
        0.165,
        "K/s",
        "Table 6.4 uses 2.5.",
    ),
    _min(
        "bore_damage",
        "f_{z,V1}^(2)",
        1445,
        "$f_{z,V_1}^{(2)}$\t$R_{z,V_1}^{(2)} = 1.5x10^{-3}$\t$m^3/s$",
        1.5e-3,
        "m3/s",
        "Table 6.4 uses 3e-3.",
    ),
    _min(
        "valve_seizing",
        "f_u^(1)",
        1446,
        "$f_u^{(1)}$\t$\\phi_u^{(1)} = 1.85x10^{-2}$\t%",
        1.85e-2,
        "%",
        "Unit ambiguity: table 6.4's 'phi_u = 25 %' is the fraction 0.25, so '1.85e-2 %' read the same way is the "
        "fraction 1.85e-4; studies.diagnosis.kpis.THESIS_MIN_DETECTABLE uses the fraction 1.85e-2 (1.85 %), which "
        "is consistent with 6.2 (25 % detected ~10 s after onset, when 1 - exp(-0.1) = 9.5 % of it, ~2.4 % of "
        "the fuel, had developed) and is the more plausible reading.",
    ),
)


# ----------------------------------------------------------------------------- false alarms
def _fa(
    cid: str,
    section: str,
    line: int,
    quote: str,
    value: str,
    note: str,
    fault: str | None = None,
    scenario: str | None = None,
    size: str = "with noise (table 6.3 noise bounds)",
    onset_s: float | None = None,
) -> ThesisClaim:
    return ThesisClaim(
        id=cid,
        section=section,
        line=line,
        quote=quote,
        kind="false_alarms",
        fault=fault,
        module=None,
        scenario=scenario,
        value=value,
        unit="-",
        size=size,
        size_pct_of_max=None,
        note=note,
        onset_s=onset_s,
    )


_Q_NOISE_BOUND_A = (
    r"was set such that  $|a_x^{(l,q)}| \leq \bar{a}_x^{(l,q)}$ , to avoid any false alarms triggered by the "
    r"detection of the sensor noise."
)
_Q_NOISE_BOUND_D = (
    r"was set such that  $|d_x^{(l,q)}| \leq \bar{d}_x^{(l,q)}$ , to avoid any false alarms triggered by the "
    r"detection of the sensor noise."
)

_FA_CLAIMS: tuple[ThesisClaim, ...] = (
    _fa(
        "6.fa/5.3.2/thresholds",
        "5.3.2",
        955,
        r"The thresholds are designed to bound the respective residuals  $\epsilon_{y_x}^{(l,q)}$  and  "
        r"$\epsilon_{y_z}^{(l,q)}$  under healthy sensor conditions.",
        "thresholds bound the residuals of healthy sensors",
        "The design claim behind every no-false-alarm statement (eq. 5.8-5.16).",
        size="no fault",
    ),
    _fa(
        "6.fa/6.1/x1",
        "6.1",
        1105,
        _Q_NOISE_BOUND_A,
        "no false alarm (noise bound)",
        "State-based residual of x^(1) (M1.1/M1.2), fig. 6.2.",
    ),
    _fa(
        "6.fa/6.1/x3",
        "6.1",
        1155,
        _Q_NOISE_BOUND_D,
        "no false alarm (noise bound)",
        "State-based residual of x^(3) (M3.1/M3.2), fig. 6.10.",
    ),
    _fa(
        "6.fa/6.1/x4",
        "6.1",
        1181,
        _Q_NOISE_BOUND_D,
        "no false alarm (noise bound)",
        "State-based residual of x^(4) (M4.1/M4.2), fig. 6.16.",
    ),
    _fa(
        "6.fa/6.2/valve_seizing",
        "6.2",
        1236,
        "In both cases, the fault was detected successfully and false alarms were avoided.",
        "no false alarm",
        "Figs. 6.21-6.22, with and without noise.",
        fault="valve_seizing",
        onset_s=20.0,
    ),
    _fa(
        "6.fa/6.2/turbine_lubrication_loss",
        "6.2",
        1274,
        "In both cases, the fault was detected successfully, with no false alarms.",
        "no false alarm",
        "Figs. 6.27-6.28, with and without noise.",
        fault="turbine_lubrication_loss",
        onset_s=30.0,
    ),
    _fa(
        "6.fa/6.2/compressor_seal_leak",
        "6.2",
        1286,
        "the sensor noise presence leads to a higher adaptive threshold, to avoid false alarms",
        "no false alarm (higher threshold)",
        "Fig. 6.30; the purpose of the higher threshold, not an observed count.",
        fault="compressor_seal_leak",
        onset_s=30.0,
    ),
    _fa(
        "6.fa/6.2/compressor_lubrication_loss",
        "6.2",
        1298,
        "In both cases, the fault was detected successfully with no false alarms.",
        "no false alarm",
        "Figs. 6.31-6.32, with and without noise.",
        fault="compressor_lubrication_loss",
        onset_s=30.0,
    ),
    _fa(
        "6.fa/6.2/intercooler_blockage",
        "6.2",
        1300,
        "Overall, the fault was detected successfully in both cases, and no false alarms were triggered.",
        "no false alarm",
        "Figs. 6.33-6.34, with and without noise.",
        fault="intercooler_blockage",
        onset_s=30.0,
    ),
    _fa(
        "6.fa/6.4.1/before-onset",
        "6.4.1",
        1382,
        r"For  $t < 175sec$ , the diagnosis set  $\mathcal{D}(t)$  is empty.",
        "empty diagnosis set before the first onset (175 s)",
        "No module fires before the first fault.",
        scenario="thesis-6.4.1",
        size=_EX_SIZE,
        onset_s=175.0,
    ),
    _fa(
        "6.fa/6.4.2/before-onset",
        "6.4.2",
        1392,
        r"For  $t < 146.1sec$ , the diagnosis set  $\mathcal{D}(t)$  is empty.",
        "empty diagnosis set before 146.1 s",
        "A no-false-alarm claim only for t < 5 s (the bore_damage onset); from 5 to 146.1 s it is the detection "
        "delay (event claims 6.4.2/event/M2.3, M2.4).",
        scenario="thesis-6.4.2",
        size=_EX_SIZE,
        onset_s=5.0,
    ),
    _fa(
        "6.fa/6.4.3/before-onset",
        "6.4.3",
        1400,
        r"For  $t < 20sec$ , the diagnosis set  $\mathcal{D}(t)$  is empty.",
        "empty diagnosis set before the first onset (20 s)",
        "No module fires before the first fault.",
        scenario="thesis-6.4.3",
        size=_EX_SIZE,
        onset_s=20.0,
    ),
    _fa(
        "6.fa/6.4.4/before-onset",
        "6.4.4",
        1410,
        r"For  $t < 15sec$ , the diagnosis set  $\mathcal{D}(t)$  is empty.",
        "empty diagnosis set before the first onset (15 s)",
        "No module fires before the first fault.",
        scenario="thesis-6.4.4",
        size=_EX_SIZE,
        onset_s=15.0,
    ),
)

CLAIMS: tuple[ThesisClaim, ...] = (
    *_SENSOR_CLAIMS,
    *_PROCESS_CLAIMS,
    *_SIGNATURE_CLAIMS,
    *_EVENT_CLAIMS,
    *_ORDER_CLAIMS,
    *_SET_CLAIMS,
    *_SPREAD_CLAIMS,
    *_MIN_CLAIMS,
    *_FA_CLAIMS,
)
_BY_ID = {c.id: c for c in CLAIMS}


def claims(kind: str | None = None) -> tuple[ThesisClaim, ...]:
    """All claims, or those of one kind (``ValueError`` for an unknown kind)."""
    if kind is None:
        return CLAIMS
    if kind not in KINDS:
        raise ValueError(f"unknown claim kind {kind!r}; allowed: {', '.join(KINDS)}")
    return tuple(c for c in CLAIMS if c.kind == kind)


def claim(claim_id: str) -> ThesisClaim:
    """The claim with this id (``KeyError`` naming the id otherwise)."""
    try:
        return _BY_ID[claim_id]
    except KeyError:
        raise KeyError(f"no thesis claim {claim_id!r}") from None


def diagnoses(c: ThesisClaim) -> tuple[tuple[str, ...], ...]:
    """The diagnoses a set claim means: its ``reading`` if given; else the printed set, extended by every
    combination of its faults when the thesis adds 'and any other combination of these faults'."""
    if c.kind not in ("interim_set", "final_set"):
        raise ValueError(f"{c.id} is not a set claim")
    if c.reading is not None:
        return c.reading
    if not c.and_combinations:
        return c.value
    faults = tuple(dict.fromkeys(f for d in c.value for f in d))
    out = list(c.value)
    for k in range(1, len(faults) + 1):
        for combo in combinations(faults, k):
            if not any(set(combo) == set(d) for d in out):
                out.append(combo)
    return tuple(out)
