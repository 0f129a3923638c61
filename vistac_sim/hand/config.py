"""Geometry and drive of the two fingertips."""

from __future__ import annotations

from dataclasses import dataclass

from vistac.config import Config, param


@dataclass(frozen=True)
class HandCfg(Config):
    """Geometry and drive of the two fingertips (sizes in metres, forces in newtons).

    The RH8D is a human-scale hand; the distal phalanx with its FTS-3 fingertip is modelled as a
    capsule of 9.5 mm radius (19 mm wide, the width of an adult distal phalanx) whose rounded end
    carries the sensor pad, behind it a shaft standing in for the middle phalanx. These sizes are
    approximations of a human-scale fingertip, not measurements of Seed Robotics CAD
    (`sim_assets/hand/README.md`).
    """

    tip_radius: float = param(0.0095, gt=0,
                              help="radius of the tip capsule (its front cap is the pad)")
    tip_half_length: float = param(0.008, ge=0,
                                   help="half length of the tip capsule's straight part")
    shaft_radius: float = param(0.0085, gt=0, help="radius of the shaft (middle phalanx)")
    shaft_length: float = param(0.045, ge=0,
                                help="drawn and collided middle phalanx behind the tip")
    height: float = param(0.012, gt=0, help="fingertip axis above the table top")
    mass: float = param(0.3, gt=0, help="kg, the moving fingertip body: the finger with the part "
                        "of the hand that moves with it (a 30 g tip alone is jolted off the "
                        "surface by a 2 N push as it slips)")
    damping: float = param(12.0, ge=0,
                           help="N s/m on the push slide, so the press settles quickly (and a "
                           "frictionless pad slides to rest within the press)")
    lateral_stiffness: float = param(
        2000.0, gt=0, help="N/m of the tip's springs across its push (sideways and up/down): "
        "the hand's compliance, which lets a tangential contact force build up as the pad slips")
    lateral_damping: float = param(50.0, ge=0, help="N s/m on the sprung slides (about critical "
                                   "with the mass: a slipping pad comes to rest on the friction "
                                   "cone's edge without overshoot)")
    press_force: float = param(2.0, gt=0, help="N, drive force along the push direction (the "
                               "hand's closing axis)")
    standoff: float = param(0.003, ge=0, help="m, gap between tip and target before the press")
    travel: float = param(0.012, gt=0, help='m, furthest the tip may move before "no contact"')
