"""Maps of a stuck axis: the state update that drops the spurious Nyquist modes of stiction.

While friction input j holds its axis at rest (the stick branch of the friction solve), its
value is the force that keeps the axis velocity at zero, v_j = c_j xi + beta_j d = 0 (c_j, beta_j
the velocity rows of C and D; ``/ Ts`` for a backward-differenced position). The state then
evolves as

    xi[k+1] = A_s xi[k] + f_k,     A_s = A - B_S beta_SS^-1 C_S,

S the set of stuck friction inputs and f_k the commands', the sliding inputs' and the held
position's part. The eigenvalues of A_s are the zeros of the friction-to-velocity path. The
Tustin friction regressors (thesis Eqn 5.18-5.25, :mod:`fdid_fmi.identify.regressors`) put
every zero at s = infinity to z = -1, so a friction path of relative degree two gives A_s a
Jordan block at -1: a force alternating from one sample to the next, growing linearly, that
the sampled position never shows. It is not physics (the continuous holding force of a stuck
axis does not alternate), and it grows until the holding force exceeds L and the axis slips:
a twin at rest crept by single-sample slips (0.1-0.3 um over 10 s on the virtual drive without
feed-forward) although the drive rested.

So at a stuck step the component of the state in the generalised eigenspace of A_s at -1
(projector P) is replaced by its steady value for this step's forcing, R f_k with
R = P (I - A_s)^-1 on that space:

    xi[k+1] = xi' + (R - P) xi' - R A_s xi[k],    xi' = A xi[k] + B u[k].

Both maps act in the k-dimensional range of P (k = the block's size, 2 for one stuck axis), so
with an orthonormal basis Q of it the step costs 3 k n products, not 2 n^2:

    g = G1 xi' - G2 xi[k],   xi[k+1] = xi' + Q g,   G1 = Q^T (R - P), G2 = Q^T R A_s.

The held position, the other outputs' smooth part and every other mode are unchanged.

Which clusters are removed: only Jordan blocks (``MIN_MULTIPLICITY`` = 2: the mode grows). A
single zero at -1 (the feed-forward twins' relative-degree-one friction path) alternates with a
constant amplitude; removing it too and identifying again made the virtual drive's feed-forward
twins' validation error 1.1-1.6x larger (README), so it is left as identified.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

NYQUIST_TOL = 1e-3          # |z + 1| below this: a Tustin image of s = infinity
MIN_MULTIPLICITY = 2        # remove the -1 cluster when it is a growing (Jordan) block


@dataclass
class StickMaps:
    """Per set of stuck friction inputs (bit j = friction input j), the update maps.

    Attributes
    ----------
    rank : list[int]    length 2**n_fric; k of the set's maps, 0 = plain update
    offset : list[int]  length 2**n_fric; where the set's Q (n x k), G1 and G2 (k x n, all
                        row-major) start in ``data``
    data : (total,) ndarray
    """

    rank: list
    offset: list
    data: np.ndarray


def stuck_dynamics(A, B, C, D, Ts, fric_inputs, vel_output, vel_diff, stuck):
    """A_s = A - B_S beta_SS^-1 C_S for the friction inputs ``stuck`` (indices into the lists).
    Returns None when beta_SS is singular (the stick branch cannot hold that set)."""
    cols = [fric_inputs[j] for j in stuck]
    rows = [C[vel_output[j]] / (Ts if vel_diff[j] else 1.0) for j in stuck]
    beta = np.array([[D[vel_output[j], c] / (Ts if vel_diff[j] else 1.0) for c in cols] for j in stuck])
    if abs(np.linalg.det(beta)) < 1e-300:
        return None
    return A - B[:, cols] @ np.linalg.solve(beta, np.array(rows))


def nyquist_maps(As):
    """(Q, G1, G2) removing the generalised eigenspace of ``As`` at -1, or None if it has fewer
    than MIN_MULTIPLICITY eigenvalues there."""
    n = As.shape[0]
    T, Z, k = sla.schur(As, output="complex", sort=lambda z: abs(z + 1.0) < NYQUIST_TOL)
    if k < MIN_MULTIPLICITY:
        return None
    # spectral projector in Schur coordinates: [[I, -X], [0, 0]], T11 X - X T22 = -T12
    X = sla.solve_sylvester(T[:k, :k], -T[k:, k:], -T[:k, k:])
    Pz = np.zeros((n, n), complex)
    Pz[:k, :k] = np.eye(k)
    Pz[:k, k:] = -X
    P = (Z @ Pz @ Z.conj().T).real
    eye = np.eye(n)
    # R = P (I - A_s)^-1 on range(P); (I - A_s) P + (I - P) is invertible (A_s commutes with P)
    R = np.linalg.solve((eye - As) @ P + (eye - P), P)
    Q = np.linalg.svd(P)[0][:, :k]          # orthonormal basis of range(P), real
    return Q, Q.T @ (R - P), Q.T @ (R @ As)


def stick_maps(model, fric_inputs, vel_output, vel_diff):
    """The :class:`StickMaps` of a DriveModel, friction inputs and their velocity sources as in
    :class:`fdid_fmi.fmu.layout.FmuLayout`."""
    nf, n = len(fric_inputs), model.n_states
    rank, offset, data = [0] * (1 << nf), [0] * (1 << nf), []
    for mask in range(1, 1 << nf):
        stuck = [j for j in range(nf) if mask >> j & 1]
        As = stuck_dynamics(model.A, model.B, model.C, model.D, model.Ts, fric_inputs, vel_output,
                            vel_diff, stuck)
        maps = nyquist_maps(As) if As is not None and n else None
        if maps is not None:
            rank[mask], offset[mask] = maps[0].shape[1], sum(x.size for x in data)
            data += [x.ravel() for x in maps]
    return StickMaps(rank=rank, offset=offset, data=np.concatenate(data) if data else np.zeros(0))
