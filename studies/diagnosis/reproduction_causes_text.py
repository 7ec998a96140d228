"""The measured cause of each ``worse`` or ``not reproduced`` row of the reproduction table, in words with
its numbers, from the outputs of :mod:`.reproduction_causes` (``docs/data/reproduction_causes/``) and the
column's own measurements.  A row whose cause no measurement in the repository shows gets none (the
table says so)."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["causes_for", "CAUSES_DIR"]

CAUSES_DIR = Path("docs/data/reproduction_causes")
LINK = "data/reproduction_causes/{}.json"  # relative to docs/
FIG = "figures/reproduction/{}.png"


def _load(name: str) -> dict | None:
    p = CAUSES_DIR / f"{name}.json"
    return json.loads(p.read_text()) if p.exists() else None


def _link(name: str) -> str:
    return f"[{name}]({LINK.format(name)})"


class _Causes:
    def __init__(self) -> None:
        self.budget = _load("budget")
        self.margins = _load("margins")
        self.timelines = _load("timelines")
        self.one = _load("one-noisy-sensor")

    # ----------------------------------------------------------------------- pieces
    def threshold(self, module: str, column: str) -> tuple[float, float, dict] | None:
        """(threshold, in noise bounds, terms) of M3.1 / M4.1 / M4.5 at full load for a column."""
        if not self.budget:
            return None
        per = self.budget["loads"]["u0=1"]
        key = {"M3.1": "M3.1", "M3.2": "M3.1", "M4.1": "M4.1", "M4.2": "M4.1", "M4.5": "M4.5", "M4.6": "M4.5"}.get(
            module
        )
        if key is None:
            return None
        readings = per[key]["readings"]
        r = readings.get(column) or readings.get("all") or readings.get("local")
        return r["total"], r["in_noise_bounds"], r["terms"]

    def one_noisy(self, case: str, reading: str = "local") -> dict | None:
        if not self.one:
            return None
        for c in self.one["cases"]:
            if c["case"] == case and reading in c["readings"]:
                return c["readings"][reading]
        return None

    def margin(self, sensor: str, module: str) -> dict | None:
        if not self.margins:
            return None
        return self.margins["offsets"].get(sensor, {}).get("modules", {}).get(module)

    def fired(self, case: str, reading: str) -> dict | None:
        if not self.timelines or case not in self.timelines:
            return None
        r = self.timelines[case]["readings"].get(reading)
        return None if r is None else r["fired"]

    # ----------------------------------------------------------------------- causes
    def fires_at_once(self, col: dict) -> str | None:
        fa = col["false_alarms"]
        n, k = fa["runs"], fa["runs_with_false_alarm"]
        if k * 2 < n:
            return None
        firsts = sorted(a["first_detection_s"] for a in fa["alarms"])
        mods = sorted({m for a in fa["alarms"] for m in a["modules"]})
        med = firsts[len(firsts) // 2]
        t = self.threshold("M3.1", col["column"])
        extra = ""
        if t is not None and col["column"] in ("thesis-no-interconnection", "thesis-table-6.1"):
            extra = (
                f"; M3.1's threshold is {t[1]:.2f} noise bounds at full load, below the noise its residual carries "
                "from "
                f"x1, x4, T1 through the forcing (the local reading's {self.threshold('M3.1', 'local')[1]:.1f}: "
                f"{_link('budget')})"
            )
        return (
            f"fires in {k} of {n} fault-free runs (median first alarm {med:.2f} s; modules {', '.join(mods)}): "
            f"the reading's thresholds do not bound the residuals' noise{extra}"
        )

    def sensor(self, sensor: str, module: str, column: str, scale: float = 1.0) -> str | None:
        from marine_fdi_env.diagnosis.modules import MODULES

        spec = next(x for x in MODULES if x.id == module)
        if sensor not in spec.all_sensors:
            return (
                f"{module} does not read {sensor}: table 6.2 gives it {', '.join(spec.all_sensors)}, so the '1' "
                "the thesis's signature table puts in this cell contradicts its own sensor sets "
                "(docs/diagnosis_structure.md)"
            )
        m = self.margin(sensor, module)
        if m is None:
            return None
        ratio = m["effect_ratio"] * scale
        if column not in ("local", "sequential") and module[:2] in ("M3", "M4") and module not in ("M4.3", "M4.4"):
            base, own = self.threshold(module, "local"), self.threshold(module, column)
            if base and own and module[:3] in ("M3.", "M4.") and module not in ("M3.3", "M3.4", "M3.5", "M4.5", "M4.6"):
                ratio *= base[0] / own[0]
        text = (
            f"{sensor}'s offset moves {module}'s noise-free residual by at most {ratio:.2f} of its threshold "
            f"within 30 s of the onset ({_link('margins')}): below about 2 the module fires only when the noise "
            "adds to the offset, so when it fires depends on the noise realisation"
        )
        one = self.one_noisy("S3.1 offset") if (sensor, module) == ("S3.1", "M3.1") else None
        if one:
            a, b = one["all sensors noisy"], one["only the checked sensor noisy"]
            text += (
                f"; with only S3.1 noisy M3.1 fires {b['median_delay_s']:.2f} s after the onset with spread "
                f"{b['spread_s']:.3f} s, against {a['median_delay_s']:.1f} s and {a['spread_s']:.1f} s with every "
                f"sensor noisy ({_link('one-noisy-sensor')}): the thesis's spreads are those of modules whose "
                "other inputs carry no noise"
            )
        return text

    def fault(self, fault: str, column: str) -> str | None:
        if fault == "turbine_seal_leak":
            t = self.threshold("M3.1", column if column != "sequential" else "local")
            one = self.one_noisy("turbine_seal_leak")
            if t is None or one is None:
                return None
            terms = t[2]
            inter = sum(
                v
                for k, v in terms.items()
                if k in ("forcing_x1", "forcing_x4", "forcing_T1", "forcing_global_interconnection")
            )
            b = one["only the checked sensor noisy"]
            return (
                f"M3.1/M3.2's threshold at full load is {t[0] / 1e3:.1f} kPa ({t[1]:.1f} noise bounds), "
                f"{inter / 1e3:.1f} kPa of it the forcing's uncertainty from the noise of x1, x4 and T1 "
                f"({_link('budget')}); the leak moves x3 by about 160 Pa within the run.  With only S3.1 noisy "
                f"M3.1 detects it in {b['fired']}/{b['runs']} runs, {b['median_delay_s']:.0f} s after the onset "
                f"({_link('one-noisy-sensor')}): the thesis's detection needs modules whose other inputs carry no noise"
            )
        if fault == "compressor_seal_leak":
            t = self.threshold("M4.1", "local")
            m4 = self.one_noisy("compressor_seal_leak", "thesis-table-6.1-m4")
            loc = self.one_noisy("compressor_seal_leak", "local")
            if t is None or m4 is None or loc is None:
                return None
            terms = t[2]
            return (
                f"M4.1/M4.2's threshold at full load is {t[1]:.2f} noise bounds: the bound d̄ itself, "
                f"{terms['injected_noise'] / terms['noise_bound']:.2f} d̄ for the noise the output injection "
                "accumulates (L/(L + 1/τ) d̄, eq. 5.14 with a valid ρ_d ≥ L) and "
                f"{(t[0] - terms['noise_bound'] - terms['injected_noise']) / terms['noise_bound']:.2f} d̄ for the "
                f"forcing ({_link('budget')}).  Table 6.1's ρ_d = 0.02 (< L = 0.3764) makes the injected-noise "
                f"term 0.1 d̄: with it (thesis-table-6.1-m4) M4.1 detects the leak "
                f"{m4['all sensors noisy']['median_delay_s']:.0f} s after the onset, against "
                f"{loc['all sensors noisy']['median_delay_s']:.0f} s; removing the other sensors' noise changes the "
                f"local reading little ({loc['only the checked sensor noisy']['median_delay_s']:.0f} s; "
                f"{_link('one-noisy-sensor')})"
            )
        if fault == "intercooler_blockage":
            t = self.threshold("M4.5", "local")
            one = self.one_noisy("intercooler_blockage")
            if t is None or one is None:
                return None
            terms = t[2]
            return (
                f"M4.5/M4.6's threshold at full load is {t[0]:.1f} K: {terms['noise_bound']:.0f} K for S4.5 and "
                f"{terms['inclusion_T_in']:.1f} K and {terms['inclusion_T_out']:.1f} K for the noise of T_in and T_out "
                f"through the compressor-outlet model ({_link('budget')}); the blockage raises T_co by 0.45 K in its "
                f"first 15 s and 4 K in 45 s.  With only S4.5 noisy M4.5 detects it "
                f"{one['only the checked sensor noisy']['median_delay_s']:.1f} s after the onset, with every sensor "
                f"noisy {one['all sensors noisy']['median_delay_s']:.0f} s ({_link('one-noisy-sensor')})"
            )
        return None

    def order(self, scenario: str, column: str) -> str | None:
        if column == "sequential":
            return (
                "the sequential diagnoser's CUSUM tests fire modules that the worst-case thresholds leave silent, and "
                "earlier (the median firing times are this row's; docs/diagnosis.md, the sequential diagnoser)"
            )
        reading = column if column in ("local", "thesis-table-6.1-m4") else "local"
        f = self.fired(scenario, reading)
        if f is None:
            return None
        fired = sorted(((v["median_first_s"], m) for m, v in f.items() if v["runs"] * 2 >= 20), key=lambda x: x[0])
        seq = ", ".join(f"{m} {t:.0f} s" for t, m in fired)
        text = f"median first firing over 20 runs: {seq} ([{scenario}]({FIG.format(scenario)}), {_link('timelines')})"
        if scenario == "thesis-6.4.4" and "M4.2" not in {m for _, m in fired}:
            m = self.margin("S3.2", "M4.2")
            if m:
                text += (
                    f"; M4.2 never fires: S3.2's offset moves its residual by {m['effect_at_onset']:.1f} Pa against a "
                    f"threshold of {m['threshold_at_onset'] / 1e3:.1f} kPa ({_link('margins')}); with table 6.1's "
                    "constants in M4.q it fires in every run"
                )
        return text


def causes_for(table: dict, cols: dict) -> dict:
    """{(column, claim id, size): cause text} for the rows whose verdict is ``worse`` or ``not reproduced``."""
    from .thesis_claims import claim

    k = _Causes()
    out = {}
    for column, rows in table.items():
        col = cols[column]
        at_once = k.fires_at_once(col)
        for r in rows:
            if r["verdict"] not in ("worse", "not reproduced"):
                continue
            c = claim(r["claim"])
            text = at_once
            if text is None:
                if c.kind in ("sensor_detection", "kpi_spread"):
                    module = r["detail"].get("module") or c.module
                    scale = 1.0
                    if c.kind == "sensor_detection" and not r["size"].startswith("table"):
                        sizes = col["sensor"][c.fault]
                        scale = sizes["noise-rule"]["magnitude"] / sizes["table"]["magnitude"]
                    text = k.sensor(c.fault, module, column, scale)
                elif c.kind in ("process_detection", "min_detectable") and c.fault:
                    text = k.fault(c.fault, column)
                elif c.kind == "event_time":
                    early, n = r["detail"].get("early", 0), r["n"]
                    if early * 2 > n:
                        order = k.order(c.scenario, column)
                        text = (
                            f"{c.module} fires before {c.fault}'s onset in {early}/{n} runs: another fault of the "
                            "example reaches it first" + (f" ({order})" if order else "")
                        )
                    elif c.fault and c.fault.startswith("S"):
                        text = k.sensor(c.fault, c.module, column)
                    else:
                        text = k.fault(c.fault, column) or k.order(c.scenario, column)
                elif c.kind in ("module_order", "final_set", "interim_set"):
                    text = k.order(c.scenario, column)
                    if c.scenario == "thesis-6.4.3":
                        extra = k.fault("compressor_seal_leak", column)
                        text = f"{text}; {extra}" if text and extra else text or extra
                elif c.kind == "process_signature":
                    speed = (
                        "the modules of Σ3 and Σ4 read the engine speed from Σ2's equations with their interconnection "
                        "sensors, so a fault of Σ2 moves them too (docs/diagnosis_structure.md)"
                    )
                    if c.fault is None or r["detail"].get("extra"):
                        text = speed
                    else:
                        text = k.fault(c.fault, column)
                elif c.kind == "false_alarms" and column == "thesis-table-6.1-m4":
                    text = (
                        "table 6.1's ρ_d = 0.02 is below the observer gain L = 0.3764, so its 0.1 d̄ does not bound the "
                        f"noise the output injection accumulates (0.95 d̄ at full load, {_link('budget')})"
                    )
            if text:
                out[(column, r["claim"], r["size"])] = text
    return out
