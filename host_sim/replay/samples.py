"""The bundled sample flights: short logs over the bundled airfield, one per text format the
host replays (docs/replay-formats.md "Sample flights"), flown by `ig demo --replay NAME`.

They are written by host_sim/replay/build_samples.py into host_sim/data/flights/, package
data, so an installed package finds them. Their positions are geodetic around the rig's
database origin ([cigi] origin, the bundled airfield's; services.rig.rigfile.CigiSpec), which
puts them over the bundled terrain when given as the replay's origin.
"""

from __future__ import annotations

from pathlib import Path

#: Where the sample logs live (package data).
FLIGHTS_DIR = Path(__file__).resolve().parents[1] / "data" / "flights"

#: Sample name -> (file in FLIGHTS_DIR, what it flies and how it is recorded). `ig demo
#: --replay`'s help and the docs read this table.
SAMPLES: dict[str, tuple[str, str]] = {
    "departure": ("departure.csv", "a take-off from runway 36 and a climbing right turn to the east, a CSV with "
                                   "GNSS at 1 Hz and AHRS at 2 Hz, cells missing column by column"),
    "circuit": ("circuit.igc", "a glider's left-hand circuit from the downwind leg to a landing on runway 36, an "
                               "IGC file with a fix each second and no attitude"),
    "low-pass": ("low-pass.fdr", "an approach to runway 36, a low pass along it and a climbing turn away, an "
                                 "X-Plane FDR file with the attitude twice a second"),
}


def sample_path(name: str) -> Path:
    """The file of a bundled sample flight.

    Raises:
        KeyError: name is not one of SAMPLES.
    """
    return FLIGHTS_DIR / SAMPLES[name][0]


def resolve_log(text: str, *, setting: str = "--replay") -> Path:
    """The log of a --replay value: a bundled sample's name, else a path to a file. A file
    whose path is a sample's name is reached as ./NAME.

    Raises:
        ValueError: neither a sample's name nor an existing file, naming setting and the value.
    """
    if text in SAMPLES:
        return sample_path(text)
    path = Path(text)
    if not path.is_file():
        raise ValueError(f"{setting}: {text!r} is neither a bundled flight ({', '.join(SAMPLES)}) nor a file")
    return path
