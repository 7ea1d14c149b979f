"""Measured first harmonics of the lap joint of docs/formats.md, for ``jointid update`` (synthetic).

The "test": the lap joint's rotational Iwan joint with ``F_S = 2.5, K_T = 1800, chi = -0.4,
beta = 0.15`` (the model file starts from 2, 2000, -0.5, 0.1), stepped sine at 0.5, 2 and 5 N
on ``B.w10``, nine dwells per level swept upwards across the resonance (the band where the
response exceeds about half its peak), the first harmonic of ``B.w10`` computed by the
harmonic balance at 21 harmonics (``jointid update`` uses 9 by default) with 0.5 % complex
Gaussian noise (seed 22), its standard error written beside.

    python tests/lap_joint_measured.py MODEL.toml OUT.csv
"""

from __future__ import annotations

import sys

import numpy as np

TRUE = {"F_S": 2.5, "K_T": 1.8e3, "chi": -0.4, "beta": 0.15}
LEVELS = (0.5, 2.0, 5.0)
DOF = "B.w10"
NOISE = 0.005


def measured_rows(model_path, seed=22, n_harmonics=21):
    from jointid.app.structure_predict import located_peak
    from jointid.app.update_joint import _with_law
    from jointid.io.structure_model import read_structure_model
    from jointid.simulate.structure import structure_from_spec
    from jointid.simulate.structure_hb import to_complex

    m, _ = structure_from_spec(read_structure_model(model_path))
    mt = _with_law(m, 0, m.joints[0].law.replace(**TRUE))
    rng = np.random.default_rng(seed)
    rows = []
    for F in LEVELS:
        c = mt.frequency_response(70.0, 86.0, F, 7)
        a = np.array([abs(to_complex(mt.modal.shape(DOF) @ p.modal)[1]) for p in c.points])
        _, ap = located_peak(c.frequency_hz, a)
        above = c.frequency_hz[a > 0.5 * ap]
        freqs = np.round(np.linspace(above.min(), above.max(), 9), 3)
        prev = None
        for f in freqs:
            prev = mt.solve(f, F, n_harmonics, guess=prev)
            X = to_complex(mt.modal.shape(DOF) @ prev.modal)[1]
            se = NOISE * abs(X)
            Xn = X + se * (rng.standard_normal() + 1j * rng.standard_normal())
            rows.append((F, float(f), DOF, float(Xn.real), float(-Xn.imag), float(se)))
    return rows


def write_measured(model_path, out):
    lines = [("# Measured first harmonics of the lap joint (synthetic: docs/formats.md, tests/lap_joint_measured.py). "
              "x = a1 cos + b1 sin [m], se the standard error of a1 and of b1."),
             "force_level,frequency_hz,dof,a1,b1,se"]
    lines += [f"{F!r},{f!r},{d},{a1:.6e},{b1:.6e},{se:.3e}" for F, f, d, a1, b1, se in measured_rows(model_path)]
    with open(out, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
    return out


if __name__ == "__main__":
    print(write_measured(sys.argv[1], sys.argv[2]))
