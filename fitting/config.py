"""Configuration of the 3D fit (config section ``fitting``)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class FitConfig:
    """uDEAS fit of the humanoid model to the 12 body landmarks (paper sections 2.4 and 4)."""

    body_height_m: float = field(
        default=1.60, metadata={"doc": "body height used for link lengths when no calibration is given",
                                "unit": "m", "range": (0.8, 2.3)}
    )
    calibration: str = field(default="", metadata={"doc": "user.yaml from `posed calibrate`; empty = none"})
    restarts: int = field(default=6, metadata={"doc": "uDEAS restarts (image mode)", "range": (1, 200)})
    row_init: int = field(default=3, metadata={"doc": "uDEAS initial row length m0", "range": (1, 30)})
    row_max: int = field(default=6, metadata={"doc": "uDEAS maximal row length mf", "range": (1, 30)})
    seed: int = field(default=0, metadata={"doc": "random seed (same seed, same result)", "range": (0, None)})
