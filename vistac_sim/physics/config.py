"""MuJoCo settings of the press and the thresholds of its checks."""

from __future__ import annotations

from dataclasses import dataclass

from vistac.config import Config, ConfigError, param


@dataclass(frozen=True)
class PhysicsCfg(Config):
    """MuJoCo settings of the press: contacts, friction, and the two phases of a press
    (`vistac_sim.physics.press`)."""

    friction: float = param(0.8, ge=0, le=10, why="MuJoCo's contact solve fails far beyond",
                            help="sliding friction coefficient, pad on object (0: "
                            "frictionless). Default 0.8: an elastomer fingertip pad on dry, "
                            "hard plastic, wood or metal (handbook values ~0.5-1.0); see the "
                            'README section "Friction"')
    timestep: float = param(0.002, gt=0, le=0.1, help="s per MuJoCo step")
    approach_steps: int = param(30, ge=1, le=1_000_000,
                                help="steps of the approach, frictionless with the tip's "
                                "lateral springs held: the pad lands and its normal force "
                                "settles")
    settle_steps: int = param(60, ge=1, le=1_000_000,
                              help="steps after the springs are released: a pad pushed outside "
                              "the friction cone slips until its force lies on the cone's edge")
    noslip_iterations: int = param(10, ge=0, le=1000,
                                   help="MuJoCo noslip iterations: no creep of a sticking pad "
                                   "(soft contacts otherwise let it slip slowly)")
    solref: tuple[float, float] = param((0.004, 1.0), help="MuJoCo solref of every contact")
    solimp: tuple[float, float, float] = param((0.99, 0.999, 0.0005), gt=0,
                                               help="MuJoCo solimp of every contact")
    max_penetration: float = param(0.001, gt=0, help="m; deeper contacts are rejected")
    max_speed: float = param(1e-3, gt=0, help="m/s; a tip still moving after settling is rejected")
    cone_tolerance_deg: float = param(3.0, ge=0, le=90,
                                      help='slack of the check "force within the friction '
                                      'cone"')
    shape_tolerance_deg: float = param(0.5, gt=0, le=90,
                                       help="max degrees between the collision geometry's "
                                       "contact normal and the labelled mesh's normal at a pad "
                                       "(bounds a frictionless label's error)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if max(self.solimp[:2]) >= 1:
            raise ConfigError("solimp", f"dmin and dmax must be < 1, got {self.solimp}")
