"""Joint laws acting side by side on the same relative motion: the force is their sum.

``Parallel((Iwan4(...), PolynomialLaw({"-q^3": k3})))`` is an Iwan joint with a cubic spring
beside it (the virtual rig's joint family).  The parameters are those of the parts, by
name (the names must not repeat); :meth:`Parallel.replace` changes them by name.  Every
protocol method is the sum of the parts' (the state: the parts' states one after the
other on the last axis); Masing's rule holds when it holds for every part with a
hysteretic state (a part without state, such as polynomial stiffness terms, keeps it only
when it stores no energy in a loop, so ``masing`` is conservative: True only when every
part is Masing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..conventions import TERMS
from ..errors import StructureError
from ._core import JointLaw, _scalar_out
from .polynomial import PolynomialLaw

__all__ = ["Parallel"]


@dataclass(frozen=True, eq=False)
class Parallel(JointLaw):
    """The sum of joint laws on one relative motion (see the module docstring)."""

    laws: tuple
    name = "parallel laws"

    def __post_init__(self):
        laws = tuple(self.laws)
        if len(laws) < 2 or not all(isinstance(x, JointLaw) for x in laws):
            raise StructureError(f"{self.name}: expected two or more joint laws, got {self.laws!r}")
        seen = {}
        for i, law in enumerate(laws):
            for k in law.parameters:
                if k in seen:
                    raise StructureError(f"{self.name}: parameter {k!r} of laws {seen[k]} and {i} would clash")
                seen[k] = i
        object.__setattr__(self, "laws", laws)

    @property
    def parameters(self) -> dict:
        return {k: v for law in self.laws for k, v in law.parameters.items()}

    @property
    def units(self) -> dict:
        return {k: v for law in self.laws for k, v in law.units.items()}

    @property
    def rate_dependent(self) -> bool:  # type: ignore[override]
        return any(law.rate_dependent for law in self.laws)

    @property
    def masing(self) -> bool:  # type: ignore[override]
        return all(law.masing for law in self.laws)

    @property
    def n_state(self) -> int:
        return sum(law.n_state for law in self.laws)

    def derived(self) -> dict:
        return {k: v for law in self.laws for k, v in law.derived().items()}

    def summary(self) -> dict:
        out = super().summary()
        out["laws"] = [law.summary() for law in self.laws]
        return out

    def replace(self, **changes):
        """A new law with parameters changed by name (each routed to the part that has it)."""
        owner = {k: i for i, law in enumerate(self.laws) for k in law.parameters}
        bad = [k for k in changes if k not in owner]
        if bad:
            raise StructureError(f"{self.name}: no parameter(s) {', '.join(bad)}; parameters: {', '.join(owner)}")
        laws = list(self.laws)
        for i, law in enumerate(laws):
            mine = {k: v for k, v in changes.items() if owner[k] == i}
            if mine and isinstance(law, PolynomialLaw):  # its parameters are named by its terms
                laws[i] = PolynomialLaw(tuple((t, mine.get(TERMS[t][0], c)) for t, c in law.terms))
            elif mine:
                laws[i] = law.replace(**mine)
        return Parallel(tuple(laws))

    def _split(self, state):
        state = np.asarray(state, float)
        out, i = [], 0
        for law in self.laws:
            out.append(state[..., i:i + law.n_state])
            i += law.n_state
        return out

    def initial_state(self, shape=()) -> np.ndarray:
        return np.concatenate([law.initial_state(shape) for law in self.laws], axis=-1)

    def force(self, u, v, state):
        f, new = 0.0, []
        for law, s in zip(self.laws, self._split(state)):
            fi, si = law.force(u, v, s)
            f = f + np.asarray(fi, float)
            new.append(np.asarray(si, float))
        return _scalar_out(f), np.concatenate(new, axis=-1)

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True):
        f = du = dv = None
        for law in self.laws:
            if velocity_jacobian:
                if law.rate_dependent:
                    fi, dui, dvi = law.aft(u_t, v_t, velocity_jacobian=True, jacobian=jacobian)
                else:
                    fi, dui = law.aft(u_t, jacobian=jacobian)
                    dvi = None if not jacobian else np.zeros_like(dui)
            else:
                fi, dui = law.aft(u_t, v_t, jacobian=jacobian) if law.rate_dependent else law.aft(u_t, jacobian=jacobian)
                dvi = None
            f = fi if f is None else f + fi
            if jacobian:
                du = dui if du is None else du + dui
                if velocity_jacobian:
                    dv = dvi if dv is None else dv + dvi
        return (f, du, dv) if velocity_jacobian else (f, du)

    def backbone(self, a):
        return _scalar_out(sum(np.asarray(law.backbone(a), float) for law in self.laws))

    def dissipation(self, a, omega=None):
        return _scalar_out(sum(np.asarray(law.dissipation(a, omega), float) for law in self.laws))

    def first_harmonic(self, a, omega=None, n: int = 4096):
        parts = [law.first_harmonic(a, omega) for law in self.laws]
        return _scalar_out(sum(np.asarray(p[0], float) for p in parts)), _scalar_out(
            sum(np.asarray(p[1], float) for p in parts))
