"""MuJoCo versions of latdyn's rotating cantilever and spin-up beam (models/*.toml).

MuJoCo 4.0 has no `<composite type="cable">` any more (the XML schema rejects the
element) and no `mujoco.elasticity.cable` plugin in the PyPI wheel; its elastic rod is
the 1D `<flexcomp dim="1">` with `<elasticity>`: a discrete elastic rod (Bergou et al.
2008), bending energy k |κb|² at each interior vertex with k = E I / (ℓ0 + ℓ1), torsion
through per-edge twist hinge joints with k_t = G J / (ℓ0 + ℓ1), no stretching (the edges
are held by soft `<edge equality="true">` constraints). The vertices are point masses
with three slide joints each.

Mapping of the latdyn model onto this rod (same physics where MuJoCo can represent it):
- Bending stiffness: circular section of radius r, I = π r⁴/4, J = π r⁴/2;
  young = EI / I, shear = GJ / J (so E I and G J are the latdyn values exactly).
- r only sets the twist inertia (MuJoCo: ½ m_e r² per edge); r = 2e-3 L gives
  ½ ρA r² = 2e-6 ρA L², latdyn's ρI_y + ρI_z of both models.
- Mass per length: lumped. flexcomp gives every vertex the same share; we set the
  free vertices to ρA h and the tip vertex to ρA h / 2 (the standard lumped mass of a
  uniform bar; with flexcomp's equal share the tip would carry ρA h/2 too much, an O(h)
  error in the frequency).
- Clamp: the first edge is pinned to the hub body (`<pin id="0 1"/>`), which clamps
  position and material frame of the root edge (MuJoCo's documented clamped end).
- Hub motion: the hub is a body on a hinge about z with armature 1e9 kg m² (the beam's
  reaction cannot change its speed measurably), and before every step its angle and
  speed are set to the prescribed law θ(t), θ̇(t) and the torque J θ̈(t) is applied:
  the hub follows the latdyn drive exactly at the step times. The rod vertices are
  children of the hub, so setting the hub speed at t = 0 starts the beam in steady
  rigid rotation, as latdyn's `[initial] angular_velocity`.
- Axial stiffness: not represented. The edges are nearly inextensible equality
  constraints (solref time constant `eq_tc`, default 2 ms), where latdyn has finite EA
  (1e5 N rotating cantilever; 2.8e7 N spin-up). The rotating-cantilever reference
  frequency is the inextensible one; latdyn's EA stretch shifts it by -0.002 %.
- Integrator: `discrete` (MuJoCo's implicit integrator for flex elasticity, the one its
  docs recommend for rods) with the Newton constraint solver, tolerance 1e-14 (with
  1e-10 the frequency error stops converging past 32 vertices: -1.7e-3 at 48, against
  +5.6e-5 with 1e-14); no numerical damping parameter (latdyn: generalized-α, ρ∞ = 0.6).
- The builders also return the total constraint-solver iterations (d.solver_niter).

Each builder returns (t, signal, wall_s): wall_s from the start of building the model
(XML compile included) to the end of the last step, in-process (interpreter start and
`import mujoco` not counted), as compare.py does for Exudyn.
"""

import math
import time

import mujoco
import numpy as np

ARMATURE = 1e9  # kg m², hub "infinitely" heavy: its speed is the prescribed one
EQ_IMP = 0.9999  # edge-constraint impedance d: (1 - d) is the constraint's softness


def grid(n, L, clamp):
    """(vertex count, spacing, x of the first vertex) of the rod with n free vertices."""
    if clamp == "edge":
        return n + 2, L / (n + 0.5), -L / (n + 0.5) / 2
    return n + 1, L / n, 0.0


def _xml(n, L, EI, GJ, rhoA, dt, eq_tc, tol, r, clamp):
    I = math.pi * r ** 4 / 4
    J = math.pi * r ** 4 / 2
    E = EI / I
    G = GJ / J
    nv, h, x0 = grid(n, L, clamp)
    eq_imp = EQ_IMP
    # the twist inertia MuJoCo derives is ½ m_e r² with m_e = mass / n: mass = ρA L
    return f"""
<mujoco>
  <option timestep="{dt!r}" integrator="discrete" solver="Newton" gravity="0 0 0"
          tolerance="{tol!r}" iterations="100">
    <flag refsafe="disable" contact="disable"/>
  </option>
  <worldbody>
    <body name="hub">
      <joint name="spin" type="hinge" axis="0 0 1" armature="{ARMATURE!r}"/>
      <geom type="sphere" size="0.01" mass="1" contype="0" conaffinity="0"/>
      <flexcomp name="rod" type="grid" dim="1" count="{nv} 1 1" spacing="{h!r} 1 1"
                mass="{rhoA * h * (nv - 1)!r}" radius="{r!r}" pos="{x0 + h * (nv - 1) / 2!r} 0 0">
        <pin id="0 1"/>
        <edge equality="true" solref="{eq_tc!r} 1" solimp="{eq_imp} {eq_imp} 0.001"/>
        <elasticity young="{E!r}" shear="{G!r}" poisson="0.3"/>
        <contact contype="0" conaffinity="0"/>
      </flexcomp>
    </body>
  </worldbody>
</mujoco>"""


def build(n, dt, L, EI, GJ, rhoA, eq_tc=0.002, tol=1e-14, clamp="edge"):
    """Compiled model and data of the clamped rod on the hub, n free vertices;
    returns (m, d, qpos address of the tip's three slides)."""
    r = 2e-3 * L
    m = mujoco.MjModel.from_xml_string(_xml(n, L, EI, GJ, rhoA, dt, eq_tc, tol, r, clamp))
    nv, h, _ = grid(n, L, clamp)
    for k in range(2, nv):  # vertices 0, 1 are pinned to the hub
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"rod_{k}")
        m.body_mass[b] = rhoA * h if k < nv - 1 else rhoA * h / 2
    d = mujoco.MjData(m)
    mujoco.mj_setConst(m, d)
    tip = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"rod_{nv - 1}")
    assert abs(m.body_pos[tip][0] - L) < 1e-9 * L
    # the vertex bodies are children of the hub with slides along the hub axes x, y, z,
    # so the tip's displacement in the hub frame is qpos[adr:adr+3] after the step
    # (d.xpos would still hold the kinematics of the start of the step)
    adr = int(m.jnt_qposadr[m.body_jntadr[tip]])
    return m, d, adr


def rotating_cantilever(omega=5.0, n_el=16, dt=0.01, t_end=12.0, L=1.0, EI=1.0, GJ=1.0,
                        rhoA=1.0, disturbance=1e-3, t_pulse=0.05, eq_tc=0.002, clamp="edge",
                        stats=None):
    """latdyn models/rotating_cantilever.toml as it was before session 18:
    unstretched start in rigid rotation, rectangular tip pulse (the shipped scene now starts
    in steady rotation with a smooth pulse). The compared quantity, the first flap
    frequency, is the same for both: the transient test gives it to 1.3e-4 … 4.3e-4 either way. Returns (t, tip z, wall_s); if `stats` is
    a dict, stats["solver_iterations"] = total constraint-solver iterations."""
    t0 = time.perf_counter()
    m, d, adr = build(n_el, dt, L, EI, GJ, rhoA, eq_tc, clamp=clamp)
    tip = int(m.jnt_bodyid[int(np.argmax(m.jnt_qposadr == adr))])
    nst = int(round(t_end / dt))
    t = np.zeros(nst + 1)
    z = np.zeros(nst + 1)
    f = disturbance / t_pulse
    d.qvel[0] = omega
    nit = 0
    for k in range(nst):
        tk = k * dt
        d.qpos[0] = omega * tk
        d.qvel[0] = omega
        # world-z tip force on [0, t_pulse): latdyn's [[loads]] pulse
        d.xfrc_applied[tip, 2] = f if tk < t_pulse - 1e-12 else 0.0
        mujoco.mj_step(m, d)
        nit += d.solver_niter[0]
        t[k + 1] = d.time
        z[k + 1] = d.qpos[adr + 2]  # hub z = world z
    wall = time.perf_counter() - t0
    if stats is not None:
        stats["solver_iterations"] = int(nit)
    return t, z, wall


def spinup_theta(ws=6.0, Ts=15.0):
    """θ(t), θ̇(t), θ̈(t) of models/spinup_beam.toml."""
    c = (Ts / (2 * math.pi)) ** 2
    w = 2 * math.pi / Ts

    def th(t):
        tau = min(t, Ts)
        return (ws / Ts) * (tau * tau / 2 + c * (math.cos(w * tau) - 1)) + ws * (t - tau)

    def thd(t):
        return ws if t >= Ts else (ws / Ts) * (t - c * w * math.sin(w * t))

    def thdd(t):
        return 0.0 if t >= Ts else (ws / Ts) * (1 - math.cos(w * t))
    return th, thd, thdd


def spinup_beam(n_el=10, dt=0.005, t_end=20.0, ws=6.0, Ts=15.0, L=10.0, EI=1.4e4,
                GJ=1.4e4, rhoA=1.2, out_dt=0.05, eq_tc=0.002, clamp="edge", stats=None):
    """latdyn models/spinup_beam.toml. Returns (t, tip deflection in the hub frame
    (hub-y component of the tip position), wall_s), sampled every out_dt; `stats` as in
    rotating_cantilever."""
    t0 = time.perf_counter()
    m, d, adr = build(n_el, dt, L, EI, GJ, rhoA, eq_tc, clamp=clamp)
    th, thd, thdd = spinup_theta(ws, Ts)
    nst = int(round(t_end / dt))
    every = int(round(out_dt / dt))
    ts, ys = [0.0], [0.0]
    nit = 0
    for k in range(nst):
        tk = k * dt
        d.qpos[0] = th(tk)
        d.qvel[0] = thd(tk)
        d.qfrc_applied[0] = ARMATURE * thdd(tk)
        mujoco.mj_step(m, d)
        nit += d.solver_niter[0]
        if (k + 1) % every == 0:
            ts.append(d.time)
            ys.append(float(d.qpos[adr + 1]))
    wall = time.perf_counter() - t0
    if stats is not None:
        stats["solver_iterations"] = int(nit)
    return np.array(ts), np.array(ys), wall
