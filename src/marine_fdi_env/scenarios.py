"""The thesis's fault scenarios (section 6.4) as named, reusable run definitions.

Each scenario fixes the parameter set, the fuel profile, the duration and a fault schedule
applied to every engine.  Magnitudes and evolution rates are left at the :class:`FaultSpec`
defaults, which are the values of thesis tables 6.3 (sensor offsets) and 6.4 (process faults).

>>> get_scenario("thesis-6.4.1").fault_specs()[1].fault_id
'S4.2'

The CLI (``marine-fdi simulate --scenario NAME``), the diagnoser and the environment share this
table; ``marine-fdi scenarios`` lists it.
"""

from __future__ import annotations

from dataclasses import dataclass

from .engine.faults import FaultSpec, parse_fault_spec

__all__ = ["Scenario", "SCENARIOS", "get_scenario", "scenario_names"]


@dataclass(frozen=True)
class Scenario:
    """A named run: ``faults`` are fault SPEC strings (``ID@ONSET[:MAGNITUDE][,key=value...]``)."""

    name: str
    description: str
    faults: tuple[str, ...]
    duration_s: float = 300.0
    profile: str = "constant:u0=1.0"
    params: str = "thesis-12v28"

    def fault_specs(self) -> list[FaultSpec]:
        """The schedule as :class:`FaultSpec` objects (thesis default magnitudes)."""
        return [parse_fault_spec(s) for s in self.faults]

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "description": self.description,
            "faults": list(self.faults),
            "duration_s": self.duration_s,
            "profile": self.profile,
            "params": self.params,
        }


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario(
            "thesis-6.4.1",
            "two sensor faults in different subsystems: turbine inlet temperature S3.4 at 175 s, "
            "charge-air pressure S4.2 at 235 s (offsets of table 6.3)",
            ("S3.4@175", "S4.2@235"),
        ),
        Scenario(
            "thesis-6.4.2",
            "two process faults: bore damage at 5 s, fuel-pump valve seizing at 200 s (table 6.4)",
            ("bore_damage@5", "valve_seizing@200"),
        ),
        Scenario(
            "thesis-6.4.3",
            "sensor and process fault: cylinder pressure S2.2 at 20 s, compressor seal leak at 30 s",
            ("S2.2@20", "compressor_seal_leak@30"),
        ),
        Scenario(
            "thesis-6.4.4",
            "sensor and process fault in one subsystem: receiver pressure S3.2 at 15 s, turbine "
            "lubrication loss at 30 s",
            ("S3.2@15", "turbine_lubrication_loss@30"),
        ),
    )
}


def scenario_names() -> list[str]:
    return list(SCENARIOS)


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name``; ``ValueError`` naming the allowed names otherwise."""
    from .suggest import lookup

    return lookup(SCENARIOS, name, "scenario")
