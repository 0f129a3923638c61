"""The press: drive both fingertips into the object, settle, read and check the contact forces.

Each tip is pushed along the hand's closing direction (`Grasp.push`; the finger's own axis may
point elsewhere) by a constant-force drive, and hangs on two sprung slides across it
(`sim_assets/hand/`). A press has two phases. The approach runs frictionless (MuJoCo's contact
override) with the lateral slides held, until the pad rests on the surface. Then friction is
switched on and the springs are released, unloaded where they are: where the push lies inside
the friction cone the pad sticks and the force follows the push; outside it the pad slips,
loading the springs, until the force lies on the cone's edge: angle(force, normal) =
min(angle(push, normal), atan(mu)). (Without the first phase, a pad that lands with some speed
slips a fraction of a millimetre on MuJoCo's soft contact before friction grips, or friction
locks it against the holds; either leaves the springs loaded and tilts a sticking force by
degrees.) The noslip solver (`PhysicsCfg`) stops the slow creep of a sticking soft contact.

Forces are read two independent ways and must agree: (1) summing `mj_contactForce` over the
pad's contacts, rotated from each contact frame to the world; (2) MuJoCo's `contact` sensor with
``reduce="netforce"`` (world frame). Both are rotated into the sensor site frame.
Every solve is checked: MuJoCo warning counters, finite state, a settled tip, penetration depth,
a contact on the sensor pad and none on the shaft. A failed check is a `RejectedSample`; nothing
that MuJoCo silently reset can reach a dataset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from vistac.dataset import FINGERS
from vistac_sim.geometry import yaw_quat
from vistac_sim.hand.grasp import Grasp
from vistac_sim.hand.ids import ModelIds
from vistac_sim.mj import mujoco
from vistac_sim.physics.checks import RejectedSample

_OVERRIDE = int(mujoco.mjtEnableBit.mjENBL_OVERRIDE)

if TYPE_CHECKING:
    from vistac_sim.generate.config import GenerateCfg


@dataclass
class PressResult:
    """A settled press, per finger (index, thumb)."""

    force_sensor: np.ndarray  # (2, 3) force of the object on each pad, N, sensor frames (method 1)
    force_sensor_check: np.ndarray  # (2, 3) from the netforce contact sensor (method 2)
    rotation: np.ndarray  # (2, 3, 3) world-from-sensor rotations
    tip: np.ndarray  # (2, 3) front-cap centre of each tip, world
    penetration: np.ndarray  # (2,) deepest penetration, m
    pad_contacts: tuple[np.ndarray, ...]  # per finger: (m, 4) contact xyz (world), normal force
    contact_normals: tuple[np.ndarray, ...] = ()  # per finger: (m, 3) collision normals (world),
    # out of the object's collision geometry towards the pad


class Press:
    """Runs presses on one compiled scene (one object); reuses its MjData."""

    def __init__(self, model: mujoco.MjModel, ids: ModelIds, cfg: GenerateCfg):
        self.model = model
        self.data = mujoco.MjData(model)
        self.ids = ids
        self.cfg = cfg
        self._f6 = np.zeros(6)
        self._limit = cfg.hand.standoff + cfg.hand.travel
        phys = cfg.physics  # contact override of the approach: the scene's contacts, no friction
        model.opt.o_friction[:] = 0.0
        model.opt.o_solref[:] = phys.solref
        model.opt.o_solimp[:] = [*phys.solimp, 0.5, 2.0]
        model.opt.o_margin = 0.0
        self._lateral = np.array(ids.lateral_qpos)
        self._finger_body = [int(model.geom_bodyid[ids.pad[f]]) for f in FINGERS]

    def pose(self, grasp: Grasp) -> None:
        """Reset the data and place the object and both finger bases for `grasp`."""
        m, d, ids, h = self.model, self.data, self.ids, self.cfg.hand
        mujoco.mj_resetData(m, d)
        m.opt.enableflags |= _OVERRIDE  # frictionless approach (see the module's docstring)
        m.opt.noslip_iterations = 0  # nothing to stop from slipping yet
        m.qpos_spring[self._lateral] = 0.0  # the last press moved them: same start every press
        m.body_pos[ids.object_body] = [grasp.object_xy[0], grasp.object_xy[1], 0.0]
        m.body_quat[ids.object_body] = yaw_quat(grasp.object_yaw)
        start = grasp.start(h.tip_radius, h.standoff)
        push, axis = grasp.push_dirs, grasp.approach
        for k, f in enumerate(FINGERS):
            # The base (and its slides) points along the push; the finger body turns to its axis.
            push_yaw = np.arctan2(push[k, 1], push[k, 0])
            d.mocap_pos[ids.mocap[f]] = [start[k, 0], start[k, 1], h.height]
            d.mocap_quat[ids.mocap[f]] = yaw_quat(push_yaw)
            m.body_quat[self._finger_body[k]] = yaw_quat(np.arctan2(axis[k, 1], axis[k, 0])
                                                      - push_yaw)
            d.ctrl[ids.actuator[f]] = h.press_force

    def release(self) -> None:
        """End of the approach: friction on, lateral springs released, unloaded where they are."""
        m, d = self.model, self.data
        m.opt.enableflags &= ~_OVERRIDE
        m.opt.noslip_iterations = self.cfg.physics.noslip_iterations
        d.eq_active[self.ids.holds] = False
        m.qpos_spring[self._lateral] = d.qpos[self._lateral]

    def run(self, grasp: Grasp) -> PressResult:
        """Press both fingers for `grasp` and return the checked, settled forces.

        Raises:
            RejectedSample: with reason "start_penetrates", "mujoco_warning", "non_finite",
                "no_contact", "shaft_contact", "not_settled" or "penetration".
        """
        m, d, phys = self.model, self.data, self.cfg.physics
        self.pose(grasp)
        mujoco.mj_forward(m, d)
        if d.ncon and (d.contact.dist[: d.ncon] < 0).any():
            raise RejectedSample("start_penetrates", "a finger starts inside the object")
        mujoco.mj_step(m, d, nstep=phys.approach_steps)
        self.release()
        mujoco.mj_step(m, d, nstep=phys.settle_steps)
        if d.warning.number.any():
            raise RejectedSample("mujoco_warning", _warnings(d))
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            raise RejectedSample("non_finite", "non-finite state after settling")
        return self._read()

    def _read(self) -> PressResult:
        m, d, ids, phys = self.model, self.data, self.ids, self.cfg.physics
        ncon = d.ncon
        contact = d.contact  # each attribute read makes a view: read each once
        g1 = contact.geom1[:ncon].tolist()
        g2 = contact.geom2[:ncon].tolist()
        dist = contact.dist[:ncon].tolist()
        frame, pos = contact.frame[:ncon], contact.pos[:ncon]
        force_w, force_c, tip = (np.zeros((2, 3)) for _ in range(3))
        rot = np.zeros((2, 3, 3))
        pen = np.zeros(2)
        pad_contacts, contact_normals = [], []
        for k, f in enumerate(FINGERS):
            pad_id, shaft_id = ids.pad[f], ids.shaft[f]
            if shaft_id in g1 or shaft_id in g2:
                raise RejectedSample("shaft_contact", f"{f} finger touches behind the pad")
            pad = [c for c in range(ncon) if g1[c] == pad_id or g2[c] == pad_id]
            if not pad or d.qpos[ids.qpos[f]] >= self._limit - 1e-6:
                raise RejectedSample("no_contact", f"{f} pad reached no surface")
            speed = math.sqrt(sum(v * v for v in d.qvel[ids.tip_dofs[f]].tolist()))
            if speed > phys.max_speed:
                raise RejectedSample("not_settled", f"{f} tip still moves at {speed:.2e} m/s")
            pen[k] = max(0.0, -min(dist[c] for c in pad))
            if pen[k] > phys.max_penetration:
                raise RejectedSample("penetration", f"{f} pad {pen[k] * 1e3:.2f} mm deep")
            rows = np.zeros((len(pad), 4))  # contact xyz, normal force
            rows[:, :3] = pos[pad]
            # the contact normal points from geom1 to geom2: out of the object when the pad is
            # geom2
            side = np.array([1.0 if g2[c] == pad_id else -1.0 for c in pad])
            contact_normals.append(frame[pad, :3] * side[:, None])
            for j, c in enumerate(pad):
                mujoco.mj_contactForce(m, d, c, self._f6)
                # mj_contactForce gives the force of geom1 on geom2 in the contact frame.
                f_on_geom2 = frame[c].reshape(3, 3).T @ self._f6[:3]
                force_w[k] += f_on_geom2 if g2[c] == pad_id else -f_on_geom2
                rows[j, 3] = self._f6[0]
            pad_contacts.append(rows)
            rot[k] = d.site_xmat[ids.site[f]].reshape(3, 3)
            adr = ids.sensor_adr[f]
            # The netforce contact sensor reports the force of geom1 (the pad) on geom2 (the
            # object) in the world frame; the pad feels the opposite.
            force_c[k] = -rot[k].T @ d.sensordata[adr:adr + 3]
            tip[k] = d.xpos[m.geom_bodyid[pad_id]]
        force_sensor = np.einsum("kji,kj->ki", rot, force_w)
        return PressResult(force_sensor, force_c, rot, tip, pen, tuple(pad_contacts),
                           tuple(contact_normals))


def _warnings(d: mujoco.MjData) -> str:
    return ", ".join(mujoco.mjtWarning(i).name.removeprefix("mjWARN_")
                     for i, w in enumerate(d.warning) if w.number)
