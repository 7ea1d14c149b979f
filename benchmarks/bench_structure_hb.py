"""Benchmark: the named multi-mode harmonic-balance case STRUCTURE_HB_CASE.

"Reduced beam, 10 modes, one 4-parameter Iwan joint in rotation, harmonics 0..7, 256 time
samples, continuation across mode 1 at three force levels":

* the seed rig's finite element beam at 120 N preload (:func:`jointid.modal.beam.seed_bolted_beam`,
  the joint stuck: its rotational spring holds the Iwan joint's ``K_T``), reduced to its lowest
  10 mass-normalised modes, modal damping 0.15 % in every mode;
* one :class:`jointid.joints.Iwan4` on the relative rotation of the joint nodes, the rig's
  parameters at 120 N (``F_S`` = 16 N m, ``K_T`` = 0.8 of the joint's rotational stiffness,
  ``chi`` = -0.3, ``beta`` = 0.4), evaluated on its discretisation of 100 sliders (plus the
  delta element); ``K_T`` is subtracted from the law (it is in the linear model);
* the shaker force ``F sin(omega t)`` at 5 cm (consistent nodal load), F = 1.5, 3, 6 N;
* pseudo-arclength continuation from 0.97 to 1.01 of the first natural frequency with
  :class:`jointid.simulate.structure_hb.CondensedHB` (condensed on the one joint coordinate:
  15 real unknowns), harmonics 0..7, 256 AFT samples, tolerance 1e-9.

Printed per force level: points, folds, Newton iterations per point, CPU ms per point, the
largest relative residual of the converged points and the peak.  Baseline in the same
process: the same points solved at fixed frequency, each from its neighbour on the curve,
by the condensed engine and by a full-DOF harmonic balance of the same 10-mode model (no
condensation: 150 real unknowns, the same AFT kernel ``CondensedHB.aft``); the two solutions
are compared.  Accuracy: the fundamental of a long DOP853 time integration started on
chosen orbits (jointid.simulate.structure_timeint) against the harmonic balance.

``--write-case DIR`` writes the case for another harmonic-balance toolbox: ``case.npz``,
Matrix Market files and ``case.json`` / ``README.md`` describing every field.

    python benchmarks/bench_structure_hb.py                        # ~1-2 min
    python benchmarks/bench_structure_hb.py --write-case case_dir  # and the case files
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time
import warnings

import numpy as np
import scipy.io
import scipy.sparse
from bench_speed import cpu_medians  # (this folder is on the path when run as a script)

from jointid._blas import single_threaded
from jointid.joints import Iwan4
from jointid.modal.beam import SEED_GEOMETRY, seed_bolted_beam
from jointid.rig.rig import SEED_RIG_DAMPING, SEED_RIG_JOINTS
from jointid.simulate.structure import JointElement, LinearModel, StructureModel
from jointid.simulate.structure_hb import to_complex, to_real
from jointid.simulate.structure_timeint import integrate_structure

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: The named case.
STRUCTURE_HB_CASE = {
    "preload": 120,
    "n_modes": 10,
    "damping_ratio": SEED_RIG_DAMPING,
    "n_sliders": 100,
    "phi_min_ratio": 1e-6,
    "n_harmonics": 7,
    "n_time": 256,
    "band": (0.97, 1.01),  # fractions of the first natural frequency
    "force_levels": (1.5, 3.0, 6.0),
    "force_position": SEED_GEOMETRY["force_position"],
    "tol": 1e-9,
}


def build_case(n_modes=None, case=STRUCTURE_HB_CASE):
    """The case as a dict: the FE matrices and DOF names, the structure model, the law and settings."""
    c = dict(case)
    if n_modes is not None:
        c["n_modes"] = int(n_modes)
    beam = seed_bolted_beam(int(c["preload"]))
    fe = beam.assemble()
    names = [""] * fe.n_dof
    for node, (iw, it) in enumerate(fe.dof_map):
        if iw >= 0:
            names[iw] = f"w{node}"
        if it >= 0:
            names[it] = f"th{node}"
    jp = SEED_RIG_JOINTS[int(c["preload"])]
    K_T = jp["stuck_fraction"] * beam.joint.k_t
    law = Iwan4(F_S=jp["F_S"], K_T=K_T, chi=jp["chi"], beta=jp["beta"], n_sliders=c["n_sliders"],
                phi_min_ratio=c["phi_min_ratio"])
    a, b = fe.joint_nodes
    dof_a, dof_b = names[fe.dof_map[a][1]], names[fe.dof_map[b][1]]
    load = fe.interpolation_matrix([c["force_position"]])[0]  # consistent nodal load of a unit force
    force = {names[i]: float(load[i]) for i in np.flatnonzero(load)}
    lin = LinearModel(fe.M, fe.K, names, zeta=c["damping_ratio"], source="seed beam")
    st = StructureModel(lin, [JointElement("joint", dof_a, dof_b, law, k_model=K_T)], force, n_modes=c["n_modes"])
    joint_sel = np.zeros(fe.n_dof)
    joint_sel[names.index(dof_a)], joint_sel[names.index(dof_b)] = -1.0, 1.0
    f1 = float(st.modal.frequencies_hz[0])
    c.update(M=np.array(fe.M), K=np.array(fe.K), dof_names=names, joint_dofs=(dof_a, dof_b), joint_selection=joint_sel,
             force_vector=load, law=law, K_T=K_T, structure=st, f1=f1,
             band_hz=(c["band"][0] * f1, c["band"][1] * f1))
    return c


def write_case(case, out_dir, results=None) -> dict:
    """Write the case for another toolbox; returns ``{file name: path}``.

    With ``results`` (of :func:`run`) also ``reference.json``: this engine's curves (frequency,
    first-harmonic joint rotation amplitude, residual of every point) to compare with.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    st, law = case["structure"], case["law"]
    e = st.engine
    Phi = np.array(st.modal.shapes)
    arrays = {
        "M": case["M"], "K": case["K"], "dof_names": np.array(case["dof_names"]),
        "joint_selection": case["joint_selection"], "force_vector": case["force_vector"],
        "Phi": Phi, "omega": e.omega, "zeta": e.zeta,
        "M_red": np.eye(e.n_modes), "K_red": np.diag(e.omega**2), "C_red": np.diag(2 * e.zeta * e.omega),
        "joint_selection_red": e.joint_shapes, "force_vector_red": e.force_shape,
        "iwan_F_S": law.F_S, "iwan_K_T": law.K_T, "iwan_chi": law.chi, "iwan_beta": law.beta,
        "iwan_n_sliders": law.n_sliders, "iwan_phi_min_ratio": law.phi_min_ratio,
        "slider_stiffness": law.sliders.stiffness, "slider_slip_force": law.sliders.slip_force,
        "k_model": e.k_model, "n_harmonics": case["n_harmonics"], "n_time": case["n_time"],
        "band_hz": np.array(case["band_hz"]), "force_levels": np.array(case["force_levels"]),
    }
    files = {"case.npz": out / "case.npz"}
    np.savez(files["case.npz"], **arrays)
    for name, mat in (("M", scipy.sparse.coo_matrix(case["M"])), ("K", scipy.sparse.coo_matrix(case["K"])),
                      ("joint_selection", case["joint_selection"][None, :]),
                      ("force_vector", case["force_vector"][:, None]), ("Phi", Phi),
                      ("M_red", arrays["M_red"]), ("K_red", arrays["K_red"]), ("C_red", arrays["C_red"]),
                      ("joint_selection_red", e.joint_shapes), ("force_vector_red", e.force_shape[:, None])):
        files[f"{name}.mtx"] = out / f"{name}.mtx"
        scipy.io.mmwrite(str(files[f"{name}.mtx"]), mat, precision=17)
    desc = {
        "case": f"reduced beam, {e.n_modes} modes, one 4-parameter Iwan joint in rotation, harmonics "
                f"0..{case['n_harmonics']}, {case['n_time']} time samples, continuation across mode 1 at "
                f"{len(case['force_levels'])} force levels",
        "equation": "M_red eta'' + C_red eta' + K_red eta + psi^T (f_iwan(u) - k_model u) = p F sin(omega t), "
                    "u = psi eta (psi = joint_selection_red, p = force_vector_red); equivalently x = Phi eta on the "
                    "FE DOFs, u = joint_selection . x, load = force_vector F sin(omega t)",
        "units": {"length": "m", "rotation": "rad", "force": "N", "moment": "N m", "frequency": "Hz (band_hz), "
                  "rad/s (omega)", "mass_matrix": "kg (translations), kg m^2 (rotations)"},
        "fields": {
            "M, K": "FE mass and stiffness matrices of the jointed cantilever (clamped DOFs removed), the joint "
                    "stuck: the rotational joint spring includes the Iwan K_T (M.mtx, K.mtx: coordinate format)",
            "dof_names": "one name per FE DOF: w<node> (deflection, m), th<node> (rotation, rad)",
            "joint_selection": f"u = joint_selection . x: relative rotation {case['joint_dofs'][1]} - "
                               f"{case['joint_dofs'][0]} of the joint nodes",
            "force_vector": f"FE load vector of a unit force at {case['force_position']:.3f} m (consistent Hermite "
                            "load; F sin(omega t) multiplies it)",
            "Phi": "the kept mass-normalised modes (n_dof x n_modes): Phi^T M Phi = M_red = I, Phi^T K Phi = K_red",
            "omega, zeta": "natural frequencies [rad/s] and modal damping ratios of the kept modes",
            "M_red, K_red, C_red": "the reduced model the case is solved on (modal damping: C_red = diag(2 zeta "
                                   "omega); damping is defined on the kept modes only)",
            "joint_selection_red, force_vector_red": "joint_selection Phi and Phi^T force_vector",
            "iwan_*": "Segalman's 4-parameter Iwan model: F_S [N m], K_T [N m/rad], chi, beta; its discretisation: "
                      "n_sliders geometric intervals from phi_min_ratio phi_max to phi_max plus [0, phi_min] and the "
                      "delta element",
            "slider_stiffness, slider_slip_force": "the discretisation actually solved: Jenkins elements in parallel "
                                                   "(N m/rad, N m), slip displacement = slip force / stiffness; "
                                                   "the sum of the stiffnesses is K_T",
            "k_model": "the joint stiffness already in K (K_T): the nonlinear force is f_iwan(u) - k_model u",
            "n_harmonics": "harmonics 0..n_harmonics (the constant term included)",
            "n_time": "AFT samples per period",
            "band_hz": "continuation range [Hz], from the lower to the upper end",
            "force_levels": "force amplitudes F [N]",
        },
        "settings": {"n_modes": int(e.n_modes), "n_harmonics": int(case["n_harmonics"]), "n_time": int(case["n_time"]),
                     "band_hz": list(case["band_hz"]), "force_levels": list(case["force_levels"]),
                     "tolerance": case["tol"], "first_natural_frequency_hz": case["f1"],
                     "joint_dofs": list(case["joint_dofs"]), "n_dof": len(case["dof_names"])},
        "files": sorted(files) + ["case.json", "README.md"] + (["reference.json"] if results else []),
    }
    if results:
        ref = {"note": "this engine's curves (CondensedHB continuation); u1: amplitude of the first harmonic of the "
                       "joint rotation [rad]; peak: the computed point of largest u1",
               "levels": [{"force": r["force"], "points": r["points"], "folds": r["folds"], "peak_hz": r["peak_hz"],
                           "peak_u1": r["peak_u"],
                           "frequency_hz": [float(q.frequency_hz) for q in r["curve"].points],
                           "u1": [float(abs(q.joint[0, 1] - 1j * q.joint[0, 2])) for q in r["curve"].points],
                           "residual": [float(q.residual_norm) for q in r["curve"].points]}
                          for r in results["levels"]],
               "time_integration": results["time_integration"]}
        files["reference.json"] = out / "reference.json"
        files["reference.json"].write_text(json.dumps(ref, indent=1) + "\n")
    files["case.json"] = out / "case.json"
    files["case.json"].write_text(json.dumps(desc, indent=2) + "\n")
    files["README.md"] = out / "README.md"
    files["README.md"].write_text(
        f"# {desc['case']}\n\n{desc['equation']}.\n\n"
        "`case.npz` holds every field (numpy: `np.load('case.npz')`); the matrices are also in Matrix Market "
        "files (`scipy.io.mmread`, MATLAB `mmread`).  `case.json` describes the fields and the settings.\n\n"
        + "".join(f"* `{k}`: {v}\n" for k, v in desc["fields"].items())
        + "\nHarmonic coefficients: x(t) = a0 + sum_k a_k cos(k omega t) + b_k sin(k omega t).\n")
    return files


class FullDOFHB:
    """Harmonic balance on all modal coordinates of a :class:`CondensedHB` model (no condensation).

    Unknowns: the ``n_modes (2H + 1)`` real coefficients of ``eta``; residual in force units
    ``Z(omega) eta + Psi^T f(Psi eta) - p F`` (Z: the modal dynamic stiffness, 2x2 blocks per
    harmonic), Jacobian ``Z + Psi^T J Psi`` with the same AFT kernel (``engine.aft``).  The
    stopping rule is the engine's: the residual as a displacement (times the receptance),
    relative to the solution, below ``tol``; Newton steps halved until that displacement
    residual falls (halving on the force residual, which the stiff high modes dominate,
    rejected good steps and took 6-8 iterations a point where the condensed Newton takes 3).
    """

    def __init__(self, engine, n_harmonics, n_time):
        self.e, self.H, self.N = engine, int(n_harmonics), int(n_time)
        self.n = 2 * self.H + 1
        self.T = np.kron(engine.joint_shapes, np.eye(self.n))

    def _Z(self, w):
        e, H, n = self.e, self.H, self.n
        Z = np.zeros((e.n_modes, n, e.n_modes, n))
        m = np.arange(e.n_modes)
        Z[m, 0, m, 0] = e.omega**2
        for k in range(1, H + 1):
            d, c = e.omega**2 - (k * w) ** 2, 2 * e.zeta * e.omega * k * w
            a, b = 2 * k - 1, 2 * k
            Z[m, a, m, a], Z[m, a, m, b], Z[m, b, m, a], Z[m, b, m, b] = d, c, -c, d
        return Z.reshape(e.n_modes * n, e.n_modes * n)

    @single_threaded  # as CondensedHB.solve: small systems, one BLAS thread
    def solve(self, omega, force, guess, tol=1e-9, max_iter=40):
        e, H, N, n = self.e, self.H, self.N, self.n
        w = float(omega)
        Z = self._Z(w)
        Hm = e.receptance(np.arange(H + 1) * w)  # (H+1, n_modes)
        Fc = np.zeros(n)
        Fc[:len(force)] = force
        pF = np.kron(e.force_shape, Fc)
        X = np.array(guess, float).reshape(-1)

        def evaluate(Xv):
            U = (self.T @ Xv).reshape(e.n_joints, n)
            F, JF, _ = e.aft(U, w, H, N, jacobian=True)
            R = Z @ Xv + self.T.T @ F.reshape(-1) - pF
            r = np.linalg.norm(to_real(Hm.T * to_complex(R.reshape(e.n_modes, n))))
            return R, JF, r, r / max(np.linalg.norm(Xv), 1e-300)

        R, JF, r, err = evaluate(X)
        it = 0
        while err >= tol and it < max_iter:
            it += 1
            step = np.linalg.solve(Z + self.T.T @ JF @ self.T, -R)
            lam = 1.0
            while True:
                Xn = X + lam * step
                Rn, JFn, rn, errn = evaluate(Xn)
                if rn < r or lam < 1e-3:
                    break
                lam *= 0.5
            X, R, JF, r, err = Xn, Rn, JFn, rn, errn
        if not err < tol:
            raise RuntimeError(f"full-DOF harmonic balance did not converge at {w:.6g} rad/s (residual {err:.3g})")
        return X.reshape(e.n_modes, n), it, err


def time_integration_check(st, point, n_periods):
    """Largest relative difference of the fundamental at every FE DOF: DOP853 run (jointid.simulate.structure_timeint)
    vs HB."""
    return integrate_structure(st, point, n_periods=n_periods).relative_difference


def run(case, repeat=3, max_steps=2000, check_points=3, n_periods=10):
    """Run the case; prints its table and returns a dict of the measured numbers per level."""
    st, e = case["structure"], case["structure"].engine
    H, N, tol = case["n_harmonics"], case["n_time"], case["tol"]
    w0, w1 = (2 * np.pi * f for f in case["band_hz"])
    full = FullDOFHB(e, H, N)
    print(f"case: {e.n_modes} modes ({st.modal.frequencies_hz[0]:.3f}-{st.modal.frequencies_hz[-1]:.1f} Hz), "
          f"one {case['law'].name} joint in rotation ({case['law'].sliders.n_elements} sliders), harmonics 0..{H}, "
          f"{N} samples, {case['band_hz'][0]:.4f}-{case['band_hz'][1]:.4f} Hz; condensed unknowns "
          f"{e.n_joints * (2 * H + 1)}, full-DOF unknowns {e.n_modes * (2 * H + 1)}")
    print(f"{'F [N]':>6} {'points':>6} {'folds':>5} {'Newton/pt':>9} {'ms/pt':>8} {'max resid':>9} "
          f"{'peak Hz':>10} {'peak u [rad]':>12} | {'fixed-f condensed':>17} {'full-DOF':>9} {'ratio':>6} "
          f"{'its c/f':>9} {'|diff|':>8}")
    results = []
    for F in case["force_levels"]:
        force = [0.0, 0.0, float(F)]

        def continue_curve(force=force):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return e.continuation(w0, w1, force, H, n_time=N, tol=tol, max_steps=max_steps)

        curve = continue_curve()
        pts = curve.points
        amp = np.array([np.abs(p.joint[0, 1] - 1j * p.joint[0, 2]) for p in pts])  # first-harmonic joint rotation
        ipk = int(np.argmax(amp))
        its = np.array([p.iterations for p in pts])
        resid = np.array([p.residual_norm for p in pts])
        guesses = [(p.omega, q) for p, q in zip(pts[1:], pts[:-1])]
        cond_out, full_out = [], []

        def fixed_condensed(force=force, guesses=guesses, cond_out=cond_out):
            cond_out[:] = [e.solve(w, force, H, n_time=N, guess=q, tol=tol) for w, q in guesses]

        def fixed_full(force=force, guesses=guesses, full_out=full_out):
            full_out[:] = [full.solve(w, force, q.modal, tol=tol) for w, q in guesses]

        t_cont, t_cond, t_full = cpu_medians([continue_curve, fixed_condensed, fixed_full], repeat)
        diff = max((np.abs(a.modal - b[0]).max() / np.abs(a.modal).max() for a, b in zip(cond_out, full_out)),
                   default=0.0)
        it_c = np.mean([p.iterations for p in cond_out]) if cond_out else 0.0
        it_f = np.mean([b[1] for b in full_out]) if full_out else 0.0
        n_fix = max(len(guesses), 1)
        row = {"force": float(F), "points": len(pts), "folds": len(curve.folds), "newton_per_point": float(its.mean()),
               "ms_per_point": t_cont * 1e3 / len(pts), "max_residual": float(resid.max()),
               "peak_hz": float(pts[ipk].frequency_hz), "peak_u": float(amp[ipk]),
               "fixed_condensed_ms": t_cond * 1e3 / n_fix, "fixed_full_ms": t_full * 1e3 / n_fix,
               "fixed_iterations": (float(it_c), float(it_f)), "condensed_vs_full": float(diff), "curve": curve}
        results.append(row)
        print(f"{F:6.2f} {len(pts):6d} {len(curve.folds):5d} {its.mean():9.2f} {row['ms_per_point']:8.2f} "
              f"{resid.max():9.1e} {row['peak_hz']:10.5f} {amp[ipk]:12.4e} | {row['fixed_condensed_ms']:14.2f} ms "
              f"{row['fixed_full_ms']:6.2f} ms {row['fixed_full_ms'] / row['fixed_condensed_ms']:5.1f}x "
              f"{it_c:4.2f}/{it_f:4.2f} {diff:8.1e}")
    print("ms/pt: CPU ms per point of the continuation (median of the runs); max resid: largest relative residual "
          "|R|/|u| of its converged points; fixed-f: the same points solved at fixed frequency from their neighbour "
          "on the curve, condensed and full-DOF (same AFT kernel), ratio full/condensed, mean Newton iterations, "
          "largest relative difference of the modal coefficients; peak: the computed point of largest first-harmonic "
          "joint rotation u")
    # where the time goes: one AFT of the joint with its Jacobian, and one Newton step's linear algebra of each form
    p = results[-1]["curve"].points[0]
    Z = full._Z(p.omega)
    JF = e.aft(p.joint, p.omega, H, N, jacobian=True)[1]
    nu = e.n_joints * (2 * H + 1)
    t_aft, t_lin_c, t_lin_f = cpu_medians([single_threaded(fn) for fn in (
        lambda: e.aft(p.joint, p.omega, H, N, jacobian=True),
        lambda: np.linalg.solve(np.eye(nu) + e.condensed(p.omega, H)[0] @ JF, np.ones(nu)),
        lambda: np.linalg.solve(Z + full.T.T @ JF @ full.T, np.ones(Z.shape[0])))], max(repeat, 5) * 4)
    print(f"one joint AFT with its exact Jacobian: {t_aft * 1e3:.2f} ms; one Newton step's linear algebra: condensed "
          f"{t_lin_c * 1e3:.3f} ms ({nu} unknowns, receptance included), full-DOF {t_lin_f * 1e3:.3f} ms "
          f"({Z.shape[0]} unknowns)")
    checks = []
    if check_points > 0:
        picks = []  # the peak of every level (the most nonlinear point), then points below the peak of the top level
        for r in results[::-1]:
            picks.append((r, int(np.argmax([np.abs(p.joint[0, 1] - 1j * p.joint[0, 2]) for p in r["curve"].points]))))
        top = results[-1]
        picks += [(top, i) for i in np.linspace(0, picks[0][1], 4).astype(int)[1:-1]]
        for r, i in picks[:check_points]:
            p = r["curve"].points[i]
            t = time.process_time()
            err = time_integration_check(st, p, n_periods)
            t_ti = time.process_time() - t
            # the truncation: the same point with 31 harmonics (a start on the orbit shows only part of it in
            # n_periods, as mode 1 settles with a time constant of 1 / (zeta omega_1), ~100 periods here)
            p31 = e.solve(p.omega, p.force, 31, n_time=1024, guess=p, tol=tol)
            X7, X31 = (st.modal.shapes @ to_complex(q.modal)[:, 1] for q in (p, p31))
            trunc = float(np.max(np.abs(X7 - X31)) / np.max(np.abs(X31)))
            checks.append({"force": r["force"], "frequency_hz": p.frequency_hz, "fundamental_difference": err,
                           "truncation_h31": trunc})
            print(f"time integration (DOP853, {n_periods} periods from the orbit) at F = {r['force']:g} N, "
                  f"{p.frequency_hz:.5f} Hz: fundamental differs from HB by {err:.2e} (relative, all DOFs; "
                  f"{t_ti:.1f} s CPU); HB with 31 harmonics moves it by {trunc:.2e}")
    return {"levels": results, "time_integration": checks}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per level (median)")
    ap.add_argument("--write-case", metavar="DIR", help="write the case's matrices and settings to DIR")
    ap.add_argument("--check-points", type=int, default=3, help="points checked by time integration")
    ap.add_argument("--periods", type=int, default=10, help="periods of each time integration")
    ap.add_argument("--n-modes", type=int, default=None, help="modes kept (default: the case's 10; smaller: a check)")
    ap.add_argument("--force-levels", default=None, help="comma-separated force amplitudes [N] (default: the case's)")
    ap.add_argument("--max-steps", type=int, default=2000, help="continuation steps per level (small: a partial curve)")
    args = ap.parse_args(argv)
    case = build_case(args.n_modes)
    if args.force_levels:
        case["force_levels"] = tuple(float(x) for x in args.force_levels.split(","))
    res = run(case, repeat=args.repeat, max_steps=args.max_steps, check_points=args.check_points,
              n_periods=args.periods)
    if args.write_case:
        files = write_case(case, args.write_case, res)
        print(f"case written to {args.write_case}: {', '.join(sorted(files))}")
    return res


if __name__ == "__main__":
    main()
