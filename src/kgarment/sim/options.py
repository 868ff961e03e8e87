"""Solver options and the per-state convergence record.

Convergence test (both solvers): the largest nodal force norm ``max_v |dE/dx_v|`` must fall
below ``tol * F_char`` with ``F_char = Y_cloth t_cloth L`` (plain cloth's membrane
stiffness times the garment's mean edge length; 0.68 N for the presets at L = 5 mm).
Why this scale: a residual force r on a cloth vertex leaves a displacement error of about
``r / (Y t)_cloth``, i.e. a strain error ``~ tol``, and an energy error
``~ sum r^2 / (Y t) ~ (tol / eps)^2`` relative to an energy at strain eps.  The default
``tol = 1e-6`` therefore gives ~1e-6 relative energy accuracy down to strains of 1e-3, and
strain (energy density) errors of 1e-6; stiffer materials only shrink the error.  Newton
converges quadratically, so the last decade costs about one iteration.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class SolverOptions:
    """Options of :func:`kgarment.sim.solve_states`.

    method : "newton" | "lbfgs";  tol : force tolerance relative to ``F_char``;
    max_iter : Newton iterations (L-BFGS: ``lbfgs_max_iter``);
    projection : Newton element Hessian PSD projection, "analytic" | "full" (9x9 eigh);
    exact_contact_hessian : full contact Hessian instead of Gauss-Newton in projected steps;
    hessian : "shifted" (exact Hessian + shift until positive definite), "adaptive"
    (projected, exact after full steps) or "projected" (see ``newton``);
    max_shifts : shift increases (x10) tried before falling back to projection;
    contact_passes : re-solves that add contact stiffness where a step enters the body;
    device : torch device for the energies;  threads : torch intra-op threads during the
    solve (restored afterwards; None leaves torch's setting).  The element arrays are
    small enough that OpenMP synchronisation costs more than it gains, badly so on a
    loaded machine (50x measured on 2 busy cores), hence 1;  use_cholmod : prefer CHOLMOD over splu;
    armijo, max_backtracks : line search;  max_step : largest nodal move per Newton step,
    in mean edge lengths;  damping_min : smallest damping ``beta / (Y t)_cloth``;
    lbfgs_history : L-BFGS memory;  on_fail : "warn" (log + flag) | "raise"
    (ConvergenceError) for states that do not converge.
    """

    method: str = "newton"
    tol: float = 1e-6
    max_iter: int = 200
    lbfgs_max_iter: int = 50000
    projection: str = "analytic"
    exact_contact_hessian: bool = False
    hessian: str = "adaptive"
    max_shifts: int = 6
    contact_passes: int = 3
    device: str = "cpu"
    threads: int | None = 1
    use_cholmod: bool = True
    armijo: float = 1e-4
    max_backtracks: int = 40
    max_step: float = 10.0
    damping_min: float = 1e-9
    lbfgs_history: int = 20
    on_fail: str = "warn"

    def __post_init__(self):
        if self.method not in ("newton", "lbfgs"):
            raise ValueError(f"unknown method {self.method!r}")
        if self.projection not in ("analytic", "abs", "full", "none"):
            raise ValueError(f"unknown projection {self.projection!r}")
        if self.hessian not in ("shifted", "adaptive", "projected"):
            raise ValueError(f"unknown hessian strategy {self.hessian!r}")
        if self.on_fail not in ("warn", "raise"):
            raise ValueError(f"on_fail must be 'warn' or 'raise', not {self.on_fail!r}")


@dataclass(frozen=True)
class Convergence:
    """What a solve did.

    converged : bool;  iterations : int;  force_max : final max nodal force norm, N;
    grad_norm : final Euclidean gradient norm, N;  tolerance : force threshold, N;
    wall_time : s;  evaluations : energy evaluations;  method : str;
    history : max nodal force norm before each iteration (and at the end), N.
    """

    converged: bool
    iterations: int
    force_max: float
    grad_norm: float
    tolerance: float
    wall_time: float
    evaluations: int
    method: str
    history: tuple[float, ...] = field(default=(), repr=False)
