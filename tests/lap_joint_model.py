"""The free-free two-beam lap joint of docs/formats.md ("Structure model"): matrices written as .npz.

Two steel Euler-Bernoulli beams (0.3 m each, 25.4 x 6.35 mm, 10 elements each; DOFs
``A.w0, A.r0, ..., B.w10, B.r10``: deflection [m] and rotation [rad] per node) joined at the
lap (``A.*10`` to ``B.*0``) by a transverse spring ``k_w`` and a rotational spring ``k_t`` (the
stuck joint), held by nothing else: two rigid-body modes.

    python tests/lap_joint_model.py OUT_FOLDER      # writes OUT_FOLDER/lap_joint.npz
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

LENGTH, WIDTH, THICK, E, RHO = 0.3, 0.0254, 0.00635, 210e9, 7850.0
N_EL = 10
K_W, K_T = 1.0e7, 2.0e3  # lap joint: transverse [N/m] and rotational [N m/rad] stiffness, stuck


def beam_matrices(length=LENGTH, n_el=N_EL):
    """Consistent mass and stiffness of a uniform beam: DOFs (w_i, r_i), i = 0..n_el."""
    A = WIDTH * THICK
    EI = E * WIDTH * THICK**3 / 12
    h = length / n_el
    k = EI / h**3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                              [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    m = RHO * A * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                      [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    n = 2 * (n_el + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(n_el):
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += k
        M[s, s] += m
    return M, K


def lap_joint_matrices():
    """``(M, K, dof_names)`` of the assembly with the stuck joint's springs in K."""
    Mb, Kb = beam_matrices()
    nb = Mb.shape[0]
    M = np.zeros((2 * nb, 2 * nb))
    K = np.zeros((2 * nb, 2 * nb))
    M[:nb, :nb] = M[nb:, nb:] = Mb
    K[:nb, :nb] = K[nb:, nb:] = Kb
    names = [f"{b}.{q}{i}" for b in "AB" for i in range(N_EL + 1) for q in "wr"]
    for q, kj in (("w", K_W), ("r", K_T)):
        a, b = names.index(f"A.{q}{N_EL}"), names.index(f"B.{q}0")
        K[np.ix_([a, b], [a, b])] += kj * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return M, K, names


def write_lap_joint(folder) -> Path:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    M, K, names = lap_joint_matrices()
    out = folder / "lap_joint.npz"
    np.savez(out, M=M, K=K, dof_names=np.array(names))
    return out


if __name__ == "__main__":
    print(write_lap_joint(sys.argv[1] if len(sys.argv) > 1 else "."))
