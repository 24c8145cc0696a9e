"""Leapfrog integration of spheres, Yade's NewtonIntegrator (YADE_MODEL.md §7).

a = F/m + g per component (blocked components 0), then optional Cundall non-viscous damping
a_i ← a_i (1 − λ_D sgn(a_i (v_i + Δt a_i/2))) (Cundall 1987; thesis eq. 3.30), v ← v + Δt a,
x ← x + Δt v; the same for spins with T/I. A body with every DOF blocked is not accelerated
but still moves with its (prescribed) velocity. Two kernels: a scene without damping runs the
undamped one. Units: SI (m, s, kg, N).
"""
from numba import njit, prange

from .kernels import kernel
from .bodies.state import DOF_ALL


@njit(inline="always", cache=True)
def _sign(x):
    """1.0, -1.0 or 0.0 (also for NaN), without a branch: in a settled bed the sign of the
    damping term is random and a branch on it is mispredicted about half the time (that cost
    4x the rest of the step's integration at 50k bodies)."""
    return (x > 0.0) * 1.0 - (x < 0.0) * 1.0


@kernel()
def leapfrog(n_local, pos, vel, angvel, force, torque, mass, inertia, blocked, gravity, dt):
    for b in prange(n_local):
        bl = blocked[b]
        if bl != DOF_ALL:
            for c in range(3):
                a = 0.0 if bl & (1 << c) else force[b, c] / mass[b] + gravity[c]
                vel[b, c] += dt * a
            for c in range(3):
                a = 0.0 if bl & (8 << c) else torque[b, c] / inertia[b]
                angvel[b, c] += dt * a
        for c in range(3):
            pos[b, c] += vel[b, c] * dt


@kernel()
def leapfrog_cundall(n_local, pos, vel, angvel, force, torque, mass, inertia, blocked, gravity, damping, dt):
    for b in prange(n_local):
        bl = blocked[b]
        if bl != DOF_ALL:
            for c in range(3):
                a = 0.0 if bl & (1 << c) else force[b, c] / mass[b] + gravity[c]
                a *= 1.0 - damping * _sign(a * (vel[b, c] + 0.5 * dt * a))
                vel[b, c] += dt * a
            for c in range(3):
                a = 0.0 if bl & (8 << c) else torque[b, c] / inertia[b]
                a *= 1.0 - damping * _sign(a * (angvel[b, c] + 0.5 * dt * a))
                angvel[b, c] += dt * a
        for c in range(3):
            pos[b, c] += vel[b, c] * dt
