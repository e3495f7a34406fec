"""What the bench's commands read from their command line and how they write their results, for the product's
(``backend/cli``) and the lab's (``lab/cli.py``) alike: the model named by ``--model``, the leg named by ``--leg``, and
a JSON file written and said."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:     # the model and the leg are loaded when a command asks for them, not when the command line starts
    from controller_core.model import QuasiStiffnessModel
    from device_bridge.sim.leg_model import LegGeometry

LEG_HELP = ("the simulated leg and person: a leg file (JSON; fields in device_bridge/sim/leg_file.py) or a repository "
            "leg's name (stiff_geared, heavy_foot, short_person); default the nominal bench")


def model_named(directory: Path | None) -> QuasiStiffnessModel:
    """The model in ``directory`` (a ``quasitune train`` output), or the default one."""
    from controller_core.model_io import load_default_model, load_model

    return load_model(directory) if directory else load_default_model()


def leg_named(leg: str | None) -> LegGeometry | None:
    """The bench leg of a leg file or a repository leg's name, None for the nominal bench (ValueError names the file,
    the field and the reason)."""
    if leg is None:
        return None
    from device_bridge.sim.leg_file import load_leg

    return load_leg(leg)


def write_json(path: Path, data: object) -> None:
    """Write ``data`` as indented JSON (creating the folder) and say so."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2))
    print(f"\nwrote {path}")
