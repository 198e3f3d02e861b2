"""The CyberGlove II sensor table, kept in one place (docs/glove.md, protocol §7).

``SENSORS[i]`` describes record index ``i`` (0-based; the thesis numbers it ``i + 1``) with the CGIU
mask slot it comes from.  Mapping code addresses sensors by these names, never by raw numbers.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sensor:
    """One bend sensor: record index (0-based), name, CGIU mask slot (0-based bit)."""

    index: int
    name: str
    slot: int


_NAMES_AND_SLOTS = (
    ("thumb_roll", 0),
    ("thumb_mcp", 1),
    ("thumb_ip", 2),
    ("thumb_abduction", 3),
    ("index_mcp", 4),
    ("index_pip", 5),
    ("index_dip", 6),
    ("middle_mcp", 8),
    ("middle_pip", 9),
    ("middle_dip", 10),
    ("index_middle_abduction", 11),
    ("ring_mcp", 12),
    ("ring_pip", 13),
    ("ring_dip", 14),
    ("middle_ring_abduction", 15),
    ("little_mcp", 16),
    ("little_pip", 17),
    ("little_dip", 18),
    ("ring_little_abduction", 19),
    ("palm_arch", 20),
    ("wrist_pitch", 21),
    ("wrist_yaw", 22),
)

SENSORS: tuple[Sensor, ...] = tuple(Sensor(i, n, s) for i, (n, s) in enumerate(_NAMES_AND_SLOTS))
SENSOR_NAMES: tuple[str, ...] = tuple(s.name for s in SENSORS)
N_SENSORS = len(SENSORS)
MASK22 = sum(1 << s.slot for s in SENSORS)
"""Hardware mask of the 22-sensor glove (0x7FFF7F)."""


def sensor_index(name: str) -> int:
    """Record index of sensor ``name`` (ValueError lists the valid names)."""
    try:
        return SENSOR_NAMES.index(name)
    except ValueError:
        raise ValueError(f"unknown glove sensor '{name}'; valid: {', '.join(SENSOR_NAMES)}") from None
