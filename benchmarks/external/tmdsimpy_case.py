"""The named harmonic-balance case of ``bench_structure_hb.py`` run in tmdsimpy and in jointid, in one process.

tmdsimpy (https://github.com/tmd-lab/tmdsimpy, MIT licence) is a harmonic-balance / AFT
toolbox for jointed structures that is not on the package index; it is not a dependency of
jointid and nothing in the project imports this file.  Make it importable (a clone on
``PYTHONPATH``; it has no packaging file) and run

    python benchmarks/bench_structure_hb.py --check-points 0 --repeat 1 --write-case /tmp/hbcase
    python benchmarks/external/tmdsimpy_case.py /tmp/hbcase

The case is solved on the same reduced matrices in both codes (``M_red``, ``K_red``,
``C_red`` of the 10 kept modes, the joint rotation ``u = psi eta``): tmdsimpy balances all
``n_modes (2 H + 1)`` modal harmonic coefficients (its ``VibrationSystem.hbm_res``, no
condensation), jointid the ``2 H + 1`` coefficients of the joint coordinate
(``CondensedHB``).  The joint law is the case's slider set (``slider_stiffness``,
``slider_slip_force``) loaded into tmdsimpy's ``VectorIwan4`` ("same law"); tmdsimpy's own
discretisation of the same four Iwan parameters (uniform midpoint sliders) is run beside it
("own law") to show what the discretisation alone moves.  ``K_T`` is in ``K_red``; the law
carries all of it, so tmdsimpy gets ``K_red - k_model psi^T psi``.

Printed: (1) agreement: each code's converged points in the other's residual, the
fixed-frequency solutions of both from the same start, the peaks of both continuations;
(2) CPU time (BLAS on one thread, medians of interleaved runs): one residual + Jacobian,
one fixed-frequency point from its neighbour (Newton), a continuation point.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time
import warnings

# one thread everywhere (jointid's engine limits BLAS to one thread itself; tmdsimpy does not)
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

try:
    import tmdsimpy
    import tmdsimpy.utils.harmonic as hutils
    from tmdsimpy.continuation import Continuation
    from tmdsimpy.nlforces.vector_iwan4 import VectorIwan4
    from tmdsimpy.solvers import NonlinearSolver
    from tmdsimpy.vibration_system import VibrationSystem
except ImportError as exc:  # not a dependency: say so and stop
    sys.exit(f"tmdsimpy is not importable ({exc}); put a clone of github.com/tmd-lab/tmdsimpy on PYTHONPATH")

from jointid.joints import DiscreteIwan
from jointid.simulate.structure_hb import CondensedHB


def load(case_dir):
    z = np.load(pathlib.Path(case_dir) / "case.npz")
    return {k: z[k] for k in z.files}


def full_model(z):
    """All modes of the FE matrices (M, K: the joint stuck), mass-normalised, with the case's damping ratio in
    every mode; returns (omega, Phi)."""
    lam, Phi = scipy.linalg.eigh(np.array(z["K"], float), np.array(z["M"], float))
    return np.sqrt(lam), Phi


def jointid_engine(z, model="reduced"):
    """The case's model from its files alone (as tests/test_bench_structure_hb.py builds it); ``full``: on all
    modes of the FE matrices."""
    law = DiscreteIwan(z["slider_stiffness"], z["slider_slip_force"])
    if model == "reduced":
        return CondensedHB(z["omega"], z["zeta"], z["joint_selection_red"], z["force_vector_red"], [law],
                           z["k_model"])
    om, Phi = full_model(z)
    return CondensedHB(om, float(z["zeta"][0]), z["joint_selection"][None, :] @ Phi, Phi.T @ z["force_vector"],
                       [law], z["k_model"])


def tmdsimpy_system(z, law="same", model="reduced"):
    """tmdsimpy's VibrationSystem with one VectorIwan4 on the joint rotation: on the reduced matrices, or
    (``full``) on the FE matrices with classical damping ``C = M Phi diag(2 zeta omega) Phi^T M``."""
    if model == "reduced":
        M, K, C = (np.array(z[k], float) for k in ("M_red", "K_red", "C_red"))
        psi = np.array(z["joint_selection_red"], float)  # (1, n_modes)
    else:
        M, K = np.array(z["M"], float), np.array(z["K"], float)
        om, Phi = full_model(z)
        MP = M @ Phi
        C = MP @ np.diag(2 * float(z["zeta"][0]) * om) @ MP.T
        psi = np.array(z["joint_selection"], float)[None, :]
    K = K - float(z["k_model"][0]) * psi.T @ psi
    vs = VibrationSystem(M, K, C=C)
    iw = VectorIwan4(psi, psi.T.copy(), kt=float(z["iwan_K_T"]), Fs=float(z["iwan_F_S"]), chi=float(z["iwan_chi"]),
                     beta=float(z["iwan_beta"]), Nsliders=int(z["iwan_n_sliders"]))
    if law == "same":  # the case's slider set: weight = stiffness, slip displacement = slip force / stiffness
        k, f = np.array(z["slider_stiffness"], float), np.array(z["slider_slip_force"], float)
        iw.Nsliders, iw.phisliders, iw.sliderweights = k.size - 1, f / k, k
        iw.init_history()
    vs.add_nl_force(iw)
    return vs


class Layout:
    """Maps jointid's modal coefficients (n_modes, 2H+1) to tmdsimpy's U (component-major: all DOFs of the
    constant, then of cos 1, sin 1, ...): ``B`` takes modal to tmdsimpy coordinates (I, or Phi on the FE DOFs)."""

    def __init__(self, z, model="reduced"):
        self.H, self.N = int(z["n_harmonics"]), int(z["n_time"])
        self.h = np.arange(self.H + 1)
        self.nc = 2 * self.H + 1
        if model == "reduced":
            self.B = np.eye(z["M_red"].shape[0])
            self.Q, self.f = z["joint_selection_red"], z["force_vector_red"]
        else:
            self.B = full_model(z)[1]
            self.Q, self.f = z["joint_selection"][None, :], z["force_vector"]
        self.n = self.B.shape[0]

    def to_tmd(self, modal):
        return (self.B @ np.asarray(modal, float)).T.reshape(-1)

    def load(self, F):
        Fl = np.zeros(self.n * self.nc)
        Fl[2 * self.n:3 * self.n] = F * self.f  # F sin(omega t): the sine of harmonic 1
        return Fl

    def joint(self, U):
        return (self.Q @ np.asarray(U, float).reshape(self.nc, self.n).T).ravel()

    def u1(self, U):
        j = self.joint(U)
        return float(np.hypot(j[1], j[2]))


def receptance_apply(vs, lay, w, R):
    """``E(w)^-1 R`` for tmdsimpy's harmonic dynamic stiffness ``E``, one diagonal block (harmonic) at a time."""
    E = hutils.harmonic_stiffness(vs.M, vs.C, vs.K, w, lay.h, calc_grad=False)[0]
    out = np.empty_like(R)
    for k in lay.h:
        sl = slice(0, lay.n) if k == 0 else slice((2 * k - 1) * lay.n, (2 * k + 1) * lay.n)
        out[sl] = np.linalg.solve(E[sl, sl], R[sl])
    return out


def newton_tmd(vs, lay, w, Fl, U0, tol=1e-9, max_iter=40):
    """Full Newton on tmdsimpy's hbm_res at fixed w, stopped like jointid's solve: on the residual as a
    displacement (the linear receptance times the force residual, harmonic by harmonic) relative to the solution."""
    U = np.array(U0, float)
    it = 0
    R, J, _ = vs.hbm_res(np.hstack((U, w)), Fl, lay.h, Nt=lay.N)
    err = np.linalg.norm(receptance_apply(vs, lay, w, R)) / np.linalg.norm(U)
    while err >= tol and it < max_iter:
        U = U - np.linalg.solve(J, R)
        it += 1
        R, J, _ = vs.hbm_res(np.hstack((U, w)), Fl, lay.h, Nt=lay.N)
        err = np.linalg.norm(receptance_apply(vs, lay, w, R)) / np.linalg.norm(U)
    return U, it, err


def tmd_displacement_residual(vs, lay, U, w, Fl):
    """|E^-1 R(U)| / |U| of tmdsimpy's hbm_res: the force residual as a displacement, relative."""
    R = vs.hbm_res(np.hstack((U, w)), Fl, lay.h, Nt=lay.N)[0]  # its hysteretic AFT has no calc_grad=False
    return float(np.linalg.norm(receptance_apply(vs, lay, w, R)) / np.linalg.norm(U))


def jointid_residual(e, lay, U, w, force):
    """jointid's condensed residual |U_j - b + G F(U_j)| / |U_j| at tmdsimpy's solution U."""
    uj = lay.joint(U)
    ev = e.evaluate(uj, w, force, lay.H, lay.N, jacobian=False)
    return float(np.linalg.norm(ev["R"]) / np.linalg.norm(uj))


VERBOSE = -1


def tmd_continuation(vs, lay, Fl, w0, w1, U0, solver, ds, xtol_rel=1e-9):
    """tmdsimpy's pseudo-arclength continuation of hbm_res from w0 to w1 (its example's settings: harmonic-wise
    conditioning, dynamic conditioning, orthogonal corrector); returns (XlamP rows, total nfev)."""
    nfev = [0]

    def fun(Uw, calc_grad=True):  # its hysteretic AFT always returns the Jacobian (no calc_grad=False)
        nfev[0] += 1  # (NonlinearSolverOMP passes jax arrays; the numpy Iwan element needs numpy)
        return vs.hbm_res(np.asarray(Uw, float), Fl, lay.h, Nt=lay.N)

    Uw0 = np.hstack((U0, w0))
    CtoP = hutils.harmonic_wise_conditioning(Uw0, lay.n, lay.h, delta=1e-3 * np.abs(U0).max())
    CtoP[-1] = abs(w1 - w0)
    dRdU = fun(Uw0)[1]
    RPtoC = 1.0 / np.max(np.abs(np.diag(dRdU * CtoP[:-1])))
    cfg = {"DynamicCtoP": True, "MaxSteps": 2000, "dsmin": ds / 50, "dsmax": ds,
           "verbose": VERBOSE, "xtol": xtol_rel * np.sqrt(Uw0.size), "corrector": "Ortho"}
    cont = Continuation(solver, ds0=ds, CtoP=CtoP, RPtoC=RPtoC, config=cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        X = cont.continuation(fun, Uw0, w0, w1)
    return X, nfev[0]


def cpu_medians(fns, repeat):
    """Median CPU seconds of each function, run in turn for ``repeat`` rounds after one warm-up round."""
    for fn in fns:
        fn()
    ts = [[] for _ in fns]
    for _ in range(repeat):
        for fn, t in zip(fns, ts):
            t0 = time.process_time()
            fn()
            t.append(time.process_time() - t0)
    return [float(np.median(t)) for t in ts]


def peak(freqs_hz, amps):
    """The largest amplitude of a curve, located between points by a parabola through the top three."""
    i = int(np.argmax(amps))
    if 0 < i < len(amps) - 1:
        x, y = np.asarray(freqs_hz[i - 1:i + 2]), np.asarray(amps[i - 1:i + 2])
        c = np.polyfit(x - x[1], y, 2)
        if c[0] < 0:
            xv = -c[1] / (2 * c[0])
            if abs(xv) <= max(abs(x[0] - x[1]), abs(x[2] - x[1])):
                return float(x[1] + xv), float(np.polyval(c, xv))
    return float(freqs_hz[i]), float(amps[i])


def run_level(F, e, vs_same, vs_own, lay, w0, w1, solvers, args):
    """One force level: agreement, then interleaved CPU times; prints and returns its row."""
    H, N = lay.H, lay.N
    force = [0.0, 0.0, float(F)]
    Fl = lay.load(F)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        curve = e.continuation(w0, w1, force, H, n_time=N, tol=1e-9)
    pts = curve.points
    f_hz = np.array([p.frequency_hz for p in pts])
    a_j = np.array([lay.u1(lay.to_tmd(p.modal)) for p in pts])
    ip = int(np.argmax(a_j))
    # the (point, neighbour) pairs checked and timed at fixed frequency: all, or --pairs of them up to the peak
    lo = 1 if not args.pairs else max(1, ip - args.pairs + 1)
    hi = len(pts) if not args.pairs else min(len(pts), lo + args.pairs)
    pairs = [(pts[i], pts[i - 1]) for i in range(lo, hi)]
    # (1) agreement: our points in tmdsimpy's residual; tmdsimpy's Newton from our neighbour point
    ours_in_theirs = [tmd_displacement_residual(vs_same, lay, lay.to_tmd(p.modal), p.omega, Fl) for p, _ in pairs]
    diffs, its_t, its_j = [], [], []
    for p, q in pairs:
        Ut, it, _ = newton_tmd(vs_same, lay, p.omega, Fl, lay.to_tmd(q.modal))
        Uo = lay.to_tmd(p.modal)
        diffs.append(np.abs(Ut - Uo).max() / np.abs(Uo).max())
        its_t.append(it)
        its_j.append(e.solve(p.omega, force, H, n_time=N, guess=q, tol=1e-9).iterations)
    # the "own law" (tmdsimpy's discretisation) at the same frequencies around the peak, from ours
    win = range(max(0, ip - 2), min(len(pts), ip + 3))
    a_own = np.array([lay.u1(newton_tmd(vs_own, lay, pts[i].omega, Fl, lay.to_tmd(pts[i].modal))[0]) for i in win])
    pk_j, pk_own = peak(f_hz, a_j), peak(f_hz[list(win)], a_own)
    # tmdsimpy's continuation (same law), each solver
    conts = {}
    for name, solver in solvers.items():
        X, nfev = tmd_continuation(vs_same, lay, Fl, w0, w1, lay.to_tmd(pts[0].modal), solver, args.ds)
        a_t = np.array([lay.u1(x[:-1]) for x in X])
        conts[name] = {"X": X, "nfev": nfev, "points": len(X), "peak": peak(X[:, -1] / (2 * np.pi), a_t),
                       "max_resid_jointid": max(jointid_residual(e, lay, x[:-1], x[-1], force) for x in X),
                       "reached_end": bool(X[-1, -1] >= w1)}
    # (2) CPU time, interleaved
    pp = pts[ip]
    Up = lay.to_tmd(pp.modal)

    def ev_j():
        e._cache = None  # the condensed receptance is rebuilt as at a new frequency
        e.evaluate(pp.joint.ravel(), pp.omega, force, H, N, jacobian=True)

    def ev_t():
        vs_same.hbm_res(np.hstack((Up, pp.omega)), Fl, lay.h, Nt=N)

    def fix_j():
        for p, q in pairs:
            e.solve(p.omega, force, H, n_time=N, guess=q, tol=1e-9)

    def fix_t():
        for p, q in pairs:
            newton_tmd(vs_same, lay, p.omega, Fl, lay.to_tmd(q.modal))

    def cont_j():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            e.continuation(w0, w1, force, H, n_time=N, tol=1e-9)

    cont_fns = {name: (lambda s=s: tmd_continuation(vs_same, lay, Fl, w0, w1, lay.to_tmd(pts[0].modal), s,
                                                    args.ds)) for name, s in solvers.items()}
    with threadpool_limits(limits=1, user_api="blas"):
        t_ev_j, t_ev_t = cpu_medians([ev_j, ev_t], max(args.repeat, 3) * 10)
        t_fix_j, t_fix_t = cpu_medians([fix_j, fix_t], args.repeat)
        tc = cpu_medians([cont_j] + list(cont_fns.values()), args.repeat)
    row = {"force": float(F), "jointid_points": len(pts), "jointid_newton_per_point": float(np.mean(
           [p.iterations for p in pts])), "jointid_peak_hz": pk_j[0], "jointid_peak_u1": pk_j[1],
           "ours_in_tmdsimpy_max_residual": float(max(ours_in_theirs)),
           "fixed_max_rel_difference": float(max(diffs)), "fixed_iterations_jointid": float(np.mean(its_j)),
           "fixed_iterations_tmdsimpy": float(np.mean(its_t)),
           "own_law_peak_hz": pk_own[0], "own_law_peak_u1": pk_own[1],
           "ms_eval_jointid": t_ev_j * 1e3, "ms_eval_tmdsimpy": t_ev_t * 1e3,
           "ms_fixed_jointid": t_fix_j * 1e3 / len(pairs), "ms_fixed_tmdsimpy": t_fix_t * 1e3 / len(pairs),
           "ms_cont_jointid": tc[0] * 1e3 / len(pts), "load_average": os.getloadavg(), "tmdsimpy_continuation": {}}
    for (name, c), t in zip(conts.items(), tc[1:]):
        row["tmdsimpy_continuation"][name] = {
            "points": c["points"], "nfev_per_point": c["nfev"] / c["points"], "ms_per_point": t * 1e3 / c["points"],
            "peak_hz": c["peak"][0], "peak_u1": c["peak"][1], "max_resid_in_jointid": c["max_resid_jointid"],
            "reached_end": c["reached_end"]}
    print(f"\nF = {F:g} N  (load average {row['load_average'][0]:.1f})")
    print(f"  agreement: {len(pairs)} of jointid's {len(pts)} points in tmdsimpy's residual (as displacement, "
          f"relative) <= "
          f"{row['ours_in_tmdsimpy_max_residual']:.1e}; fixed-f Newton of both from the neighbour: solutions "
          f"within {row['fixed_max_rel_difference']:.1e}, iterations {row['fixed_iterations_jointid']:.2f} "
          f"(jointid) / {row['fixed_iterations_tmdsimpy']:.2f} (tmdsimpy)")
    print(f"  peak (parabola through the top 3 points): jointid {pk_j[0]:.5f} Hz, u1 {pk_j[1]:.5e} rad; "
          f"tmdsimpy's own Iwan discretisation at the same frequencies: {pk_own[0]:.5f} Hz "
          f"({(pk_own[0] / pk_j[0] - 1) * 100:+.4f} %), u1 {pk_own[1]:.5e} ({(pk_own[1] / pk_j[1] - 1) * 100:+.3f} %)")
    print(f"  CPU ms: residual+Jacobian jointid {t_ev_j * 1e3:.3f} / tmdsimpy {t_ev_t * 1e3:.3f} "
          f"(x{t_ev_t / t_ev_j:.1f}); fixed-f point (Newton, same start, same stopping rule) "
          f"{row['ms_fixed_jointid']:.2f} / {row['ms_fixed_tmdsimpy']:.2f} "
          f"(x{row['ms_fixed_tmdsimpy'] / row['ms_fixed_jointid']:.1f})")
    print(f"  continuation: jointid {len(pts)} points, {row['ms_cont_jointid']:.2f} ms/point, peak "
          f"{pk_j[0]:.5f} Hz")
    for name, c in row["tmdsimpy_continuation"].items():
        print(f"  continuation: tmdsimpy[{name}] {c['points']} points{'' if c['reached_end'] else ' (STOPPED)'}, "
              f"{c['nfev_per_point']:.1f} evaluations/point, {c['ms_per_point']:.2f} ms/point "
              f"(x{c['ms_per_point'] / row['ms_cont_jointid']:.1f}), peak {c['peak_hz']:.5f} Hz "
              f"({(c['peak_hz'] / pk_j[0] - 1) * 100:+.5f} %), u1 {c['peak_u1']:.5e} "
              f"({(c['peak_u1'] / pk_j[1] - 1) * 100:+.4f} %), its points in jointid's residual <= "
              f"{c['max_resid_in_jointid']:.1e}")
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case_dir")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--levels", default=None, help="comma-separated force levels (default: the case's)")
    ap.add_argument("--model", choices=("reduced", "full"), default="reduced",
                    help="tmdsimpy on the reduced matrices (the case) or on the FE matrices (all modes in both codes)")
    ap.add_argument("--solvers", default="hybr,newton", help="tmdsimpy solvers: hybr (its default), newton (jax)")
    ap.add_argument("--ds", type=float, default=0.3, help="tmdsimpy's initial arclength step (conditioned)")
    ap.add_argument("--pairs", type=int, default=0, help="check and time this many points up to the peak (0: all)")
    ap.add_argument("--json", default=None, help="write the numbers to this file")
    args = ap.parse_args(argv)
    z = load(args.case_dir)
    lay = Layout(z, args.model)
    e = jointid_engine(z, args.model)
    vs_same, vs_own = tmdsimpy_system(z, "same", args.model), tmdsimpy_system(z, "own", args.model)
    H, N = lay.H, lay.N
    w0, w1 = 2 * np.pi * z["band_hz"]
    levels = z["force_levels"] if args.levels is None else [float(x) for x in args.levels.split(",")]
    wanted = args.solvers.split(",")
    solvers = {"hybr": NonlinearSolver()} if "hybr" in wanted else {}
    if "newton" in wanted:
        try:
            from tmdsimpy.jax.solvers import NonlinearSolverOMP
            solvers["newton"] = NonlinearSolverOMP(config={"max_steps": 20, "reform_freq": 1, "verbose": False,
                                                            "stopping_tol": ["xtol"]})
        except ImportError as exc:
            print(f"(tmdsimpy's NonlinearSolverOMP not available: {exc})")
    out = {"levels": [], "load_average_start": os.getloadavg()}
    print(f"tmdsimpy {pathlib.Path(tmdsimpy.__file__).parent}; load average {os.getloadavg()}")
    print(f"case: {e.n_modes} modes ({args.model} model), harmonics 0..{H}, {N} samples, "
          f"{z['band_hz'][0]:.4f}-{z['band_hz'][1]:.4f} Hz; "
          f"unknowns: jointid {e.n_joints * lay.nc} (condensed), tmdsimpy {lay.n * lay.nc} (+1 frequency)")
    out["model"] = args.model
    for F in levels:
        out["levels"].append(run_level(F, e, vs_same, vs_own, lay, w0, w1, solvers, args))
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
