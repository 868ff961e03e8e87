"""Solver options and the per-state convergence record.

Convergence test (both solvers): every vertex's force, measured against the stiffness
around it, must be small::

    residual = max_v |dE/dx_v| / (s_v L)  <=  tol

with ``s_v`` the largest membrane stiffness ``Y t`` (N/m) of the elements around v (at
least plain cloth's) and L the garment's mean edge length.  Why: a residual force r on a
vertex of stiffness ~s_v leaves a displacement error ~ r / s_v = residual * L, i.e. a
strain error ~residual and a relative energy error ~(residual / eps)^2 at strain eps.  The
default ``tol = 1e-5`` therefore gives ~1e-6 relative energy accuracy for strains of 1% and
more (measured on the three-motion shirt: 5e-7 at residual 5e-4), and energy densities
accurate to ~1e-5.  Tighter is possible but slow: slack / taut transitions of wrinkled
triangles (the relaxed energy is only C1 at l_max = 1) make the last decades linear.
Equilibria are not unique to better than about 1% in per-face energy density: solves
converged to 1e-5 with different solver settings land up to 2.4% apart (a membrane without
bending on a frictionless body has many nearly equal equilibria; ``benchmarks/accuracy.py``),
so design iterations use 1e-3 (``kgarment.problem.SolverSpec``); every tolerance's value is in
:mod:`kgarment.constants`.
A single cloth-based force scale (``Y_cloth t_cloth L``) would demand displacements of
1e-11 m inside the 1000x stiffer reinforced cloth of the ``paper`` preset -- below what
the piecewise (slack / taut) energy lets any solver reach -- and add no accuracy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from kgarment.constants import ADAPTIVE_VERTICES, FRICTION_LAGS, MAX_NEWTON, SOLVER_TOL

FACTORIZATIONS = ("auto", "pardiso", "simplicial", "supernodal", "splu")


@dataclass(frozen=True)
class SolverOptions:
    """Options of :func:`kgarment.sim.solve_states`.

    method : "newton" | "lbfgs";  tol : tolerance on the scaled residual (module doc);
    max_iter : Newton iterations (L-BFGS: ``lbfgs_max_iter``);
    projection : Newton element Hessian PSD projection, "analytic" | "full" (9x9 eigh);
    exact_contact_hessian : full contact Hessian instead of Gauss-Newton in projected steps;
    hessian : "shifted" (exact Hessian + shift until positive definite), "adaptive"
    (projected, exact after full steps), "projected", or "auto" ("adaptive" on garments of
    more than ``ADAPTIVE_VERTICES`` vertices, else "shifted"; see ``newton``);
    max_shifts : shift increases (x10) tried before falling back to projection;
    rescue_shifts : for a state that did not converge (or stalled), one more solve allowing
    this many shift increases (0: none), from the same start where the solve stopped early
    (stalled, stuck), from where it stopped where it ran out of ``max_iter``
    (``serial._rescue``).  Measured: an arm-sleeve
    state of a BESO run stalled at residual 1.5 with the projected fallback and converged
    in 89 iterations with 6; on the shirt, 6 from the start costs 20-50% more iterations,
    hence only as a rescue;
    extrapolate : try step lengths 2, 4, ... 64 after a full step that decreased the energy
    by more than 3/4 of the linear prediction (negative curvature: sliding, buckling);
    contact_passes : re-solves that add contact stiffness where a step enters the body
    (``newton._anticipate``); None: 1 for ``tol >= 1e-3``, else 3 (``passes``);
    device : torch device for the energies;  threads : torch intra-op and BLAS threads
    during the solve (restored afterwards; None leaves them; ``solve.blas_threads``).  The
    arrays are small enough that thread synchronisation costs more than it gains, badly so
    on a loaded machine (50x measured on 2 busy cores), hence 1;  workers : processes
    solving states in parallel (``parallel``; e.g. 2 on 2 cores; 1 = in this process);
    use_cholmod : False forces SciPy's splu;
    factorization : "auto" (MKL PARDISO when installed, else CHOLMOD simplicial), "pardiso",
    CHOLMOD's "simplicial" LDL' or "supernodal" LL', or SciPy's "splu"
    (``assembly.SparseCholesky``);
    armijo, max_backtracks : line search;  max_step : largest nodal move per Newton step,
    in mean edge lengths;  damping_min : smallest damping ``beta / (Y t)_cloth``;
    lbfgs_history : L-BFGS memory;  friction_lags : with skin-garment friction, re-solves
    with the normal forces of the last equilibrium, at most (``serial._with_friction``);
    lag_contact : the vertices the last Newton step brought onto the surface keep their
    contact model in the next factorisation (``newton._anticipate``); None: at the design
    loop's tolerances (``tol >= 1e-3``), not below (``lagged``);  on_fail : "warn" (log + flag) | "raise"
    (ConvergenceError) | "info" (flag, logged at INFO: for a caller that solves such states
    again another way) for states that do not converge.
    """

    method: str = "newton"
    tol: float = SOLVER_TOL
    max_iter: int = MAX_NEWTON
    lbfgs_max_iter: int = 50000
    projection: str = "analytic"
    exact_contact_hessian: bool = False
    hessian: str = "shifted"
    max_shifts: int = 3
    rescue_shifts: int = 6
    extrapolate: bool = True
    contact_passes: int | None = None
    device: str = "cpu"
    threads: int | None = 1
    workers: int = 1
    use_cholmod: bool = True
    factorization: str = "auto"
    armijo: float = 1e-4
    max_backtracks: int = 40
    max_step: float = 10.0
    damping_min: float = 1e-9
    lbfgs_history: int = 20
    friction_lags: int = FRICTION_LAGS
    lag_contact: bool | None = None
    on_fail: str = "warn"

    @property
    def passes(self) -> int:
        """Contact anticipation passes: ``contact_passes``, or by tolerance.  Measured on the
        three-motion shirt (6 warm states after a 1.5% design change, 3 designs, PARDISO):
        at tol 1e-3 one pass takes 447 Newton iterations against 609 for three at
        subdivision 1 (267 against 283 at subdivision 0; the main job 82 against 104 s), at
        1e-2 as many; at 1e-5 three take 1,829 and one 2,758, with 3 states stopped
        unconverged: the extra passes pay once the contact set must be exact."""
        if self.contact_passes is not None:
            return self.contact_passes
        return 1 if self.tol >= 1e-3 else 3

    @property
    def lagged(self) -> bool:
        """Whether Newton lags the anticipated contact set (``lag_contact``, or by tolerance).
        Measured on the main job (subdivision 0, 2 workers, 2026-11-26, back to back): the
        design loop in 91 s and 5,117 Newton iterations against 152 s and 6,338.  Lagged at
        the final evaluation's 1e-4 too it stalled (5 of the 6 fully reinforced states
        stopped at residuals 1.1-1.8e-4: a vertex held on the surface one step too long,
        again and again), hence not below 1e-3."""
        if self.lag_contact is not None:
            return self.lag_contact
        return self.tol >= 1e-3

    def strategy(self, n_vertices: int) -> str:
        """The Hessian strategy for a garment of ``n_vertices`` (``hessian``, "auto" resolved)."""
        if self.hessian != "auto":
            return self.hessian
        return "adaptive" if n_vertices > ADAPTIVE_VERTICES else "shifted"

    def __post_init__(self):
        if self.method not in ("newton", "lbfgs"):
            raise ValueError(f"unknown method {self.method!r}")
        if self.projection not in ("analytic", "abs", "full", "none"):
            raise ValueError(f"unknown projection {self.projection!r}")
        if self.hessian not in ("shifted", "adaptive", "projected", "auto"):
            raise ValueError(f"unknown hessian strategy {self.hessian!r}")
        if self.factorization not in FACTORIZATIONS:
            raise ValueError(f"factorization must be one of {', '.join(map(repr, FACTORIZATIONS))}, "
                             f"not {self.factorization!r}")
        if self.on_fail not in ("warn", "raise", "info"):
            raise ValueError(f"on_fail must be 'warn', 'raise' or 'info', not {self.on_fail!r}")


@dataclass(frozen=True)
class Convergence:
    """What a solve did.

    converged : bool;  iterations : int;  residual : final scaled residual (dimensionless,
    module doc);  tolerance : its threshold;  force_max : final max nodal force norm, N;
    grad_norm : final Euclidean gradient norm, N;  wall_time : s;  evaluations : energy
    evaluations;  method : str;  history : residual before each iteration (and at the end).
    """

    converged: bool
    iterations: int
    residual: float
    tolerance: float
    force_max: float
    grad_norm: float
    wall_time: float
    evaluations: int
    method: str
    history: tuple[float, ...] = field(default=(), repr=False)
