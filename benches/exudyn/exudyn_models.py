"""Exudyn versions of latdyn's rotating cantilever, spin-up beam and flapping blade.

Element: ObjectBeamGeometricallyExact (Exudyn's 3D geometrically exact Simo-Reissner beam:
two nodes, linear interpolation of positions and rotations). Beam nodes: NodeRigidBodyEP
(Euler parameters). Hub: an ObjectRigidBody on a NodeRigidBodyRxyz at the origin with
coordinates 0..4 fixed by CoordinateConstraints and its z angle driven (constant speed: a
velocity-level CoordinateConstraint ψ̇z = Ω, no user function; spin-up: a position-level
CoordinateConstraint with a Python offset user function θ(t)). The beam root is attached
to the hub by an ObjectJointGeneric: all six axes locked (clamp) or the hub-y rotation
free (flap hinge of the blade). Shear stiffness GA = EA (EI/(GA L²) ≤ 1e-5: effectively
Euler-Bernoulli, the physics of latdyn's Bernoulli beam); section inertia from the
latdyn models' rhoIy, rhoIz (torsional rhoJ = rhoIy + rhoIz).

Solver: exu.SolveDynamic with Exudyn's implicit generalized-α (index-3, default modified
Newton, default relative tolerance 1e-8), spectral radius 0.6 (as latdyn's models),
linear solver EigenSparse (about 2x faster here than the default dense solver at 16
elements). Spin-up beam only: Newton absolute tolerance 1e-6 (residual in N) instead of
the default 1e-10 -- with the default, Newton stalls at relative errors ~1e-5 at
t ≈ 0.06 s (the residual of the barely moving beam is at round-off level) and the solver
stops at the minimum step size.

Each builder returns (t, signal, wall_s), wall_s = time spent in SolveDynamic (model
building, a few ms, is excluded; see compare.py for the process-level timing).
"""

import math
import time

import numpy as np
import exudyn as exu
from exudyn.itemInterface import (
    NodeRigidBodyEP, NodeRigidBodyRxyz, NodePointGround, ObjectGround,
    ObjectBeamGeometricallyExact, MarkerNodeCoordinate, MarkerNodeRigid,
    MarkerBodyRigid, ObjectRigidBody, ObjectConnectorCoordinate, ObjectJointGeneric, Force,
    SensorNode, SensorBody,
)

EP0 = [1.0, 0.0, 0.0, 0.0]


def _rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _euler_params(R):
    """Unit quaternion (Euler parameters, scalar first) of a rotation matrix."""
    t = np.trace(R)
    e0 = 0.5 * math.sqrt(max(1.0 + t, 0.0))
    return [e0, (R[2, 1] - R[1, 2]) / (4 * e0), (R[0, 2] - R[2, 0]) / (4 * e0),
            (R[1, 0] - R[0, 1]) / (4 * e0)]


def _settings(t_end, dt, rho_inf, out_dt, abs_tol=None):
    s = exu.SimulationSettings()
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    if abs_tol is not None:
        s.timeIntegration.newton.absoluteTolerance = abs_tol
    s.timeIntegration.numberOfSteps = int(round(t_end / dt))
    s.timeIntegration.endTime = t_end
    s.timeIntegration.generalizedAlpha.spectralRadius = rho_inf
    s.timeIntegration.verboseMode = 0
    s.displayStatistics = False
    s.displayComputationTime = False
    s.solutionSettings.writeSolutionToFile = False
    s.solutionSettings.sensorsWritePeriod = out_dt
    return s


def _build_beam(mbs, L, n_el, sec, tilt=0.0, omega0=0.0):
    """Straight beam from the origin along R_y(-tilt) e_x (tilted up by `tilt`), n_el
    elements; initial rigid rotation omega0 about z. Returns node list."""
    R = _rot_y(-tilt)  # x axis tilted towards +z by tilt
    ex = R[:, 0]
    ep_ref = _euler_params(R)
    le = L / n_el
    nodes = []
    for i in range(n_el + 1):
        p = ex * (le * i)
        v = np.cross([0, 0, omega0], p)
        if True:
            # EP rates for angular velocity w (world): ė = ½ [0,w] ⊗ e
            e0, e1, e2, e3 = ep_ref
            w = [0, 0, omega0]
            # quaternion product [0,w] ⊗ e
            de = 0.5 * np.array([
                -(w[0] * e1 + w[1] * e2 + w[2] * e3),
                w[0] * e0 + w[1] * e3 - w[2] * e2,
                -w[0] * e3 + w[1] * e0 + w[2] * e1,
                w[0] * e2 - w[1] * e1 + w[2] * e0,
            ])
            n = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(p) + list(ep_ref),
                                            initialVelocities=list(v) + list(de)))
        nodes.append(n)
    for i in range(n_el):
        mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[nodes[i], nodes[i + 1]],
                                                   physicsLength=le, sectionData=sec))
    return nodes


def _section(EA, EIy, EIz, GJ, rhoA, rhoIy, rhoIz, GA=None):
    sec = exu.BeamSection()
    GA = EA if GA is None else GA
    sec.stiffnessMatrix = np.diag([EA, GA, GA, GJ, EIy, EIz])
    sec.massPerLength = rhoA
    sec.inertia = np.diag([rhoIy + rhoIz, rhoIy, rhoIz])
    return sec


def _hub(mbs, root, theta=None, omega_const=None, hinge_y=False, omega0=0.0):
    """Hub: rigid body (mass 1, inertia 1) on a NodeRigidBodyRxyz at the origin, its
    coordinates 0..4 fixed, its z angle driven (velocity-level constraint ψ̇z = Ω for a
    constant speed, no user function; else position-level with a Python offset user
    function θ(t)). The beam's root node is attached by an ObjectJointGeneric: all six
    axes locked (clamp) or the hub-y rotation free (flap hinge)."""
    nh = mbs.AddNode(NodeRigidBodyRxyz(referenceCoordinates=[0] * 6,
                                       initialVelocities=[0, 0, 0, 0, 0, omega0]))
    bh = mbs.AddObject(ObjectRigidBody(nodeNumber=nh, physicsMass=1.0,
                                       physicsInertia=[1, 1, 1, 0, 0, 0]))
    g = mbs.AddNode(NodePointGround(referenceCoordinates=[0, 0, 0]))
    mg = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=g, coordinate=0))
    for c in range(5):
        m = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nh, coordinate=c))
        mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[mg, m]))
    m5 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nh, coordinate=5))
    if omega_const is not None:
        mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[mg, m5], velocityLevel=True,
                                                offset=omega_const))
    else:
        def off(mbs_, t, item, lOffset):
            return theta(t)
        mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[mg, m5],
                                                offsetUserFunction=off))
    mh = mbs.AddMarker(MarkerBodyRigid(bodyNumber=bh, localPosition=[0, 0, 0]))
    mr = mbs.AddMarker(MarkerNodeRigid(nodeNumber=root))
    axes = [1, 1, 1, 1, 0, 1] if hinge_y else [1] * 6
    mbs.AddObject(ObjectJointGeneric(markerNumbers=[mh, mr], constrainedAxes=axes))


def rotating_cantilever(omega=5.0, n_el=16, dt=0.01, t_end=12.0, rho_inf=0.6,
                        L=1.0, EI=1.0, GJ=1.0, EA=1.0e5, rhoA=1.0, disturbance=1e-3,
                        t_pulse=0.05, out_dt=None):
    """latdyn models/rotating_cantilever.toml as it was before session 18:
    unstretched start in rigid rotation, rectangular tip pulse (the shipped scene now starts
    in steady rotation with a smooth pulse). The compared quantity, the first flap
    frequency, is the same for both: the transient test gives it to 1.3e-4 … 4.3e-4 either way. Returns (t, tip z, wall_s)."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    rI = 1e-6 * rhoA * L ** 2
    sec = _section(EA, EI, EI, GJ, rhoA, rI, rI)
    nodes = _build_beam(mbs, L, n_el, sec, omega0=omega)
    _hub(mbs, nodes[0], omega_const=omega, omega0=omega)
    mtip = mbs.AddMarker(MarkerNodeRigid(nodeNumber=nodes[-1]))
    f = disturbance / t_pulse
    ld = mbs.AddLoad(Force(markerNumber=mtip, loadVector=[0, 0, f]))
    state = {"on": True}

    def prestep(mbs_, t):
        if state["on"] and t >= t_pulse - 1e-12:
            mbs_.SetLoadParameter(ld, "loadVector", [0, 0, 0])
            state["on"] = False
        return True

    mbs.SetPreStepUserFunction(prestep)
    sens = mbs.AddSensor(SensorNode(nodeNumber=nodes[-1], storeInternal=True,
                                    writeToFile=False,
                                    outputVariableType=exu.OutputVariableType.Position))
    mbs.Assemble()
    s = _settings(t_end, dt, rho_inf, out_dt or dt)
    t0 = time.perf_counter()
    exu.SolveDynamic(mbs, s)
    wall = time.perf_counter() - t0
    d = mbs.GetSensorStoredData(sens)
    return d[:, 0], d[:, 3], wall


def spinup_theta(ws=6.0, Ts=15.0):
    c = (Ts / (2 * math.pi)) ** 2

    def theta(t):
        tau = min(t, Ts)
        return (ws / Ts) * (tau * tau / 2 + c * (math.cos(2 * math.pi * tau / Ts) - 1)) \
            + ws * (t - tau)
    return theta


def spinup_beam(n_el=10, dt=0.005, t_end=20.0, rho_inf=0.6, ws=6.0, Ts=15.0, L=10.0,
                EA=2.8e7, EI=1.4e4, GJ=1.4e4, rhoA=1.2, out_dt=0.05, abs_tol=1e-6):
    """latdyn models/spinup_beam.toml. Returns (t, tip deflection in hub frame, wall_s)."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    rI = rhoA * (L / 1000) ** 2
    sec = _section(EA, EI, EI, GJ, rhoA, rI, rI)
    nodes = _build_beam(mbs, L, n_el, sec)
    theta = spinup_theta(ws, Ts)
    _hub(mbs, nodes[0], theta=theta)
    sens = mbs.AddSensor(SensorNode(nodeNumber=nodes[-1], storeInternal=True,
                                    writeToFile=False,
                                    outputVariableType=exu.OutputVariableType.Position))
    mbs.Assemble()
    s = _settings(t_end, dt, rho_inf, out_dt, abs_tol)
    t0 = time.perf_counter()
    exu.SolveDynamic(mbs, s)
    wall = time.perf_counter() - t0
    d = mbs.GetSensorStoredData(sens)
    t = d[:, 0]
    th = np.array([theta(x) for x in t])
    y_hub = -np.sin(th) * d[:, 1] + np.cos(th) * d[:, 2]
    return t, y_hub, wall


def flapping_blade(omega=6.0, n_el=10, dt=0.005, t_end=10.0, rho_inf=0.6, tilt=0.157,
                   L=5.0, EI=4375.0, GJ=5000.0, EA=1.0e8, rhoA=10.0, out_dt=0.01):
    """latdyn models/flapping_blade.toml: blade hinged at the axis (flap hinge = the root
    node's free Tait-Bryan y angle), tilted up by `tilt`, hub at constant omega.
    Returns (t, tip z, wall_s)."""
    t, z, _, wall = flapping_blade_signals(omega, n_el, dt, t_end, rho_inf, tilt, L, EI, GJ,
                                           EA, rhoA, out_dt, moment=False)
    return t, z, wall


def flapping_blade_signals(omega=6.0, n_el=10, dt=0.005, t_end=10.0, rho_inf=0.6, tilt=0.157,
                           L=5.0, EI=4375.0, GJ=5000.0, EA=1.0e8, rhoA=10.0, out_dt=0.01,
                           moment=True):
    """As `flapping_blade`, also the flapwise bending moment at mid-span (latdyn sensor
    `mid_moment`): the mean of the local y torques (`TorqueLocal`) of the two elements
    that meet at mid-span (Exudyn's linear element has one moment per element, at its
    midpoint; the mean is the mid-span value to O(h²)), so n_el must be even.
    Returns (t, tip z, mid-span moment or None, wall_s)."""
    if moment and n_el % 2:
        raise ValueError("flapping_blade_signals: n_el must be even for the mid-span moment")
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    rI = rhoA * (L / 500) ** 2
    sec = _section(EA, EI, 100 * EI, GJ, rhoA, rI, rI)
    nodes = _build_beam(mbs, L, n_el, sec, tilt=tilt, omega0=omega)
    _hub(mbs, nodes[0], omega_const=omega, hinge_y=True, omega0=omega)
    sens = mbs.AddSensor(SensorNode(nodeNumber=nodes[-1], storeInternal=True,
                                    writeToFile=False,
                                    outputVariableType=exu.OutputVariableType.Position))
    msens = []
    if moment:
        # the beam elements are objects 0 .. n_el-1 (added first by _build_beam)
        msens = [mbs.AddSensor(SensorBody(bodyNumber=b, localPosition=[0, 0, 0],
                                          storeInternal=True, writeToFile=False,
                                          outputVariableType=exu.OutputVariableType.TorqueLocal))
                 for b in (n_el // 2 - 1, n_el // 2)]
    mbs.Assemble()
    s = _settings(t_end, dt, rho_inf, out_dt)
    t0 = time.perf_counter()
    exu.SolveDynamic(mbs, s)
    wall = time.perf_counter() - t0
    d = mbs.GetSensorStoredData(sens)
    m = None
    if moment:
        m = np.mean([mbs.GetSensorStoredData(x)[:, 2] for x in msens], axis=0)
    return d[:, 0], d[:, 3], m, wall
