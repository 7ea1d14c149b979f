"""A measured backbone of a two-mass structure with a Jenkins joint, from a simulated ring-down (synthetic).

The structure (docs/formats.md "Measured backbones for updating", ``two_mass.toml``): masses
1 and 0.5 kg in a chain, ``x1`` to ground 4e4 N/m, ``x1`` to ``x2`` 2e4 N/m, modal damping
0.2 %, a Jenkins joint from ``x1`` to ground (``kt = 3000`` N/m, ``Fs = 1`` N: the "test";
the model file starts from 2500 and 1.25).  The ring-down is integrated here in physical
coordinates, independently of jointid's harmonic balance and of its joint laws: classical
Runge-Kutta at ``substeps`` steps per sample, the slider held over a step (the joint force
``clip(kt (x1 - s), -Fs, Fs)`` inside it, exact while it sticks or slides on) and moved at the
step's end, through the extremum where the velocity changes sign inside the step (cubic
Hermite interpolation).  The release: mode 1's linear shape at ``x2 = 3 mm`` (the joint sliding
at ``Fs``), at rest.  The acceleration of ``x2`` gets Gaussian noise (``noise`` times the
largest sample), then the project's ring-down analysis (:func:`jointid.signal.ringdown.modal_ringdown`:
band-pass around mode 1, windows of ``n_cycles`` periods) gives the backbone: displacement
amplitude of ``x2``, natural frequency and damping ratio with their standard errors.

    python tests/two_mass_backbone.py OUT.csv
"""

from __future__ import annotations

import math
import sys

import numpy as np

TRUE = {"kt": 3.0e3, "Fs": 1.0}
ZETA = 0.002
DOF = "x2"
M = (1.0, 0.5)
K = ((6e4, -2e4), (-2e4, 2e4))

#: The model file of docs/formats.md (modal data of the chain without the joint).
MODEL_TOML = """# file: two_mass.toml
[model]
name = "two masses, Jenkins joint to ground"

[modal]                           # M = diag(1, 0.5) kg, x1-ground 4e4 N/m, x1-x2 2e4 N/m
frequencies_hz = [22.507907903927652, 45.015815807855304]
damping_ratios = [0.002, 0.002]
dof_names = ["x1", "x2"]
shapes = [[0.5773502691896258, 0.816496580927726], [1.1547005383792517, -0.816496580927726]]

[[joint]]
name = "slip"
dofs = ["x1"]                     # x1 to ground
law = "jenkins"
parameters = { kt = 2.5e3, Fs = 1.25 }

[force]
dofs = { "x2" = 1.0 }

[response]
dofs = ["x2"]
"""


def _damping(zeta):
    Mm, Kk = np.diag(M), np.array(K)
    lam, V = np.linalg.eigh(np.diag(1 / np.sqrt(M)) @ Kk @ np.diag(1 / np.sqrt(M)))
    Phi = np.diag(1 / np.sqrt(M)) @ V  # mass-normalised
    return Mm @ Phi @ np.diag(2 * zeta * np.sqrt(lam)) @ Phi.T @ Mm


def free_decay(kt=TRUE["kt"], Fs=TRUE["Fs"], x2_0=1e-2, duration=8.0, fs=2000.0, substeps=4, zeta=ZETA):
    """``(t, acceleration of x2)`` of the ring-down (module doc), sampled at ``fs``."""
    C = _damping(zeta)
    c11, c12, c21, c22 = float(C[0, 0]), float(C[0, 1]), float(C[1, 0]), float(C[1, 1])
    (k11, k12), (k21, k22) = K
    m1, m2 = M
    us = Fs / kt

    def acc(x1, x2, v1, v2, s):
        f = kt * (x1 - s)
        f = min(max(f, -Fs), Fs)
        return ((-c11 * v1 - c12 * v2 - k11 * x1 - k12 * x2 - f) / m1, (-c21 * v1 - c22 * v2 - k21 * x1 - k22 * x2) / m2)

    def play(u, s):
        d = u - s
        return u - us if d > us else (u + us if d < -us else s)

    x1, x2, v1, v2 = 0.5 * x2_0, x2_0, 0.0, 0.0  # mode 1's shape x1 / x2 = 1/2 (without the joint)
    s = play(x1, 0.0)
    h = 1.0 / (fs * substeps)
    n = round(duration * fs)
    out = np.empty(n)
    for i in range(n):
        out[i] = acc(x1, x2, v1, v2, s)[1]
        for _ in range(substeps):
            a1, a2 = acc(x1, x2, v1, v2, s)
            b1, b2 = acc(x1 + 0.5 * h * v1, x2 + 0.5 * h * v2, v1 + 0.5 * h * a1, v2 + 0.5 * h * a2, s)
            c1, c2 = acc(x1 + 0.5 * h * (v1 + 0.5 * h * a1), x2 + 0.5 * h * (v2 + 0.5 * h * a2),
                         v1 + 0.5 * h * b1, v2 + 0.5 * h * b2, s)
            d1, d2 = acc(x1 + h * (v1 + 0.5 * h * b1), x2 + h * (v2 + 0.5 * h * b2), v1 + h * c1, v2 + h * c2, s)
            nx1 = x1 + h * (v1 + h * (a1 + b1 + c1) / 6)
            nx2 = x2 + h * (v2 + h * (a2 + b2 + c2) / 6)
            nv1 = v1 + h * (a1 + 2 * b1 + 2 * c1 + d1) / 6
            nv2 = v2 + h * (a2 + 2 * b2 + 2 * c2 + d2) / 6
            if v1 * nv1 < 0:  # x1 turns inside the step: the slider first sees the extremum (Hermite cubic)
                # x(th) = h00 x0 + h10 h v0 + h01 x1 + h11 h v1; its derivative's root in (0, 1)
                A = 6 * (x1 - nx1) / h + 3 * (v1 + nv1)
                B = -6 * (x1 - nx1) / h - 4 * v1 - 2 * nv1
                roots = np.roots([A, B, v1]) if A != 0 else np.array([-v1 / B])
                roots = [r.real for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and 0 <= r.real <= 1]
                if roots:
                    th = roots[0]
                    h00, h10 = 2 * th**3 - 3 * th**2 + 1, th**3 - 2 * th**2 + th
                    h01, h11 = -2 * th**3 + 3 * th**2, th**3 - th**2
                    s = play(h00 * x1 + h10 * h * v1 + h01 * nx1 + h11 * h * nv1, s)
            x1, x2, v1, v2 = nx1, nx2, nv1, nv2
            s = play(x1, s)
    return np.arange(n) / fs, out


def backbone_rows(t, accel, rng=None, noise=2e-3, n_cycles=12.0, hop_cycles=12.0, half_width=0.5):
    """``(dof, amplitude, frequency_hz, se_frequency_hz, damping_ratio, se_damping_ratio)`` per window of the
    noisy record's ring-down analysis (windows below the noise floor left out)."""
    from jointid.signal.ringdown import dominant_frequency, modal_ringdown

    rng = np.random.default_rng(rng)
    x = accel + noise * np.abs(accel).max() * rng.standard_normal(accel.size)
    f0 = dominant_frequency(t, x, (15.0, 35.0))
    d = modal_ringdown(t, x, frequency_hz=f0, half_width=half_width * f0, n_cycles=n_cycles, hop_cycles=hop_cycles)
    b = d.backbone()
    return [(DOF, float(a), float(w / (2 * math.pi)), float(sw / (2 * math.pi)), float(z), float(sz))
            for a, w, sw, z, sz in zip(b.amplitude, b.omega, b.omega_stderr, b.zeta, b.zeta_stderr)]


def write_backbone(out, rows, header="# Backbone of x2 from a simulated ring-down (synthetic: tests/two_mass_backbone.py)"
                                      ". amplitude: first harmonic of the displacement of x2 [m]."):
    lines = [header, "dof,amplitude,frequency_hz,se_frequency_hz,damping_ratio,se_damping_ratio,mode"]
    lines += [f"{d},{a:.6e},{f:.8f},{sf:.3e},{z:.6e},{sz:.3e},1" for d, a, f, sf, z, sz in rows]
    with open(out, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
    return out


def write_example(out, seed=7):
    t, a = free_decay()
    return write_backbone(out, backbone_rows(t, a, seed))


if __name__ == "__main__":
    print(write_example(sys.argv[1]))
