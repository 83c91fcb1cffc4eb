"""Paper A's whole-body TO of one scenario: the problem transcribed as term calls
(:mod:`locoman.to.transcription.transcribe`), assembled over the robot's compiled terms
(:mod:`locoman.to.nlp.ipopt`), and solved by IPOPT, first with the configured Hessian
(Gauss-Newton by default) and, where that has not converged after
``exact_after_iterations`` or has stalled (``exact_when_stalled``), on from its primal-dual
point with the exact one.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np

from locoman.config.to import BACKENDS, SolveCfg, averaged_over_nodes
from locoman.to.collisions.pairs import CollisionPair
from locoman.to.nlp.derivatives import load_derivatives
from locoman.to.nlp.ipopt import BlockNLP, NLPResult, parameter_vector, structure_key
from locoman.to.nlp.multipliers import carried_multipliers, row_owners
from locoman.to.problem.inputs import TOInputs, guided_by
from locoman.to.problem.modes import node_modes
from locoman.to.problem.numbers import Numbers, node_parameters
from locoman.to.problem.schedule import build_schedule
from locoman.to.solve.bounds import bounds
from locoman.to.solve.initial_guess import initial_guess
from locoman.to.solve.trajectory import Trajectory
from locoman.to.terms.library import all_kinds, g1_terms
from locoman.to.terms.supports import Support
from locoman.to.transcription.transcribe import Transcription, transcribe

log = logging.getLogger(__name__)


def _base_index(support: Support | None) -> int:
    """The supporting object's index, -1 for the world or none."""
    base = getattr(support, "base", None)
    return -1 if base is None else base


class TrajectoryOptimizer:
    """The TO of one scenario. Its terms are the robot's compiled set (built, or loaded
    from ``cache_dir``, the first time); a solve transcribes the problem as data and
    reassembles the NLP only where its structure changed (another collision set, other
    keyframe switches need none: they are numbers).

    Args:
        inputs: The scenario.
        cfg: The ``solve`` section: schedule, weights, contact, collision, solver.
        cache_dir: Where compiled terms are cached (``solver.compile``); None interprets them.
    """

    def __init__(self, inputs: TOInputs, cfg: SolveCfg, cache_dir: Path | None) -> None:
        tic = time.perf_counter()
        inputs = guided_by(inputs, cfg.keyframes)
        self.inputs, self.cfg = inputs, cfg
        self.schedule = build_schedule(inputs, cfg.schedule)
        self.modes = node_modes(inputs, self.schedule)
        weights = cfg.weights
        if weights.average_over_nodes:
            weights = averaged_over_nodes(weights, self.schedule.nodes)
        self.numbers = Numbers(
            weights, cfg.contact, cfg.collision, inputs.objects, inputs.obstacles
        )
        self.robot = g1_terms()
        compiled = cache_dir if cfg.solver.compile else None
        self.derivatives = load_derivatives(
            [k.term for k in all_kinds(self.robot)], compiled, cfg.solver.compile_flags
        )
        solver = cfg.solver
        self._ipopt = {
            **BACKENDS[solver.backend],
            "max_iter": solver.max_iterations,
            "tol": solver.tolerance,
            "constr_viol_tol": solver.constraint_tolerance,
            "print_level": solver.print_level,
            "print_frequency_iter": 1,
            "sb": "yes",
            "mu_strategy": "adaptive",
            "fixed_variable_treatment": "make_parameter",
            "max_soc": solver.second_order_corrections,
        }
        if solver.backend == "ipopt_mumps" and not solver.mumps_scaling:
            self._ipopt |= {"mumps_scaling": 0, "mumps_permuting_scaling": 0}
        if solver.max_wall_time_s is not None:
            self._ipopt["max_wall_time"] = float(solver.max_wall_time_s)
        exact = solver.hessian == "exact"
        self.switch_at = None if exact else solver.exact_after_iterations
        if self.switch_at is not None and self.switch_at >= solver.max_iterations:
            self.switch_at = None
        self._nlps: dict[tuple[str, str], BlockNLP] = {}
        self._last: Transcription | None = None
        self._transcribed_s = 0.0
        self.transcription = self.transcribe()
        self.nlp = self._nlp(self.transcription, solver.hessian)
        # The rest of the set-up: the terms' loading (or compiling), schedule, modes.
        self._set_up_s = time.perf_counter() - tic - self._transcribed_s - self.nlp.build_time_s

    @property
    def build_time_s(self) -> float:
        """Time spent building: loading (or compiling) the terms, every transcription and
        the assembly of every NLP so far [s]."""
        assembled = sum(nlp.build_time_s for nlp in self._nlps.values())
        return self._set_up_s + self._transcribed_s + assembled

    def transcribe(
        self, numbers: Numbers | None = None, pairs: list[CollisionPair] | None = None
    ) -> Transcription:
        """The problem as data with these numbers (default: the optimizer's) and the
        configuration's keyframe costs (9), (10)."""
        tic = time.perf_counter()
        numbers = numbers or self.numbers
        inputs = dataclasses.replace(self.inputs, objects=numbers.objects)
        P = node_parameters(
            inputs,
            self.schedule,
            keyframe_base=self.cfg.keyframe_base,
            keyframe_foot=self.cfg.keyframe_foot,
        )
        # The last transcription's pair calls serve the next whose pairs extend its own (a
        # round of found pairs).
        self._last = transcribe(self.modes, P, numbers, self.robot, pairs, self._last)
        self._transcribed_s += time.perf_counter() - tic
        return self._last

    def _nlp(
        self, transcription: Transcription, hessian: str, limits: dict | None = None
    ) -> BlockNLP:
        """The assembled NLP of ``transcription``'s structure, reused where it is known."""
        key = (structure_key(transcription.n_x + transcription.n_y, transcription.blocks), hessian)
        if key not in self._nlps:
            first = (
                {}
                if self.switch_at is None or hessian == "exact"
                else {"max_iter": self.switch_at, **self._stall_options()}
            )
            settled = self._settled_options() if hessian == "exact" else {}
            # The latest NLP of this Hessian: a round's problem extends it.
            latest = [nlp for (_, h), nlp in self._nlps.items() if h == hessian]
            self._nlps[key] = BlockNLP(
                transcription.n_x,
                transcription.blocks,
                transcription.rows,
                self.derivatives,
                hessian,
                self._ipopt | first | settled,
                transcription.n_y,
                latest[-1] if latest else None,
                self.cfg.solver.progress_every,
            )
        return self._nlps[key]

    def _stall_options(self) -> dict:
        """IPOPT's "acceptable" stop as the first phase's stall test: the objective's
        relative change under ``exact_when_stalled`` for 10 iterations, with the scaled
        error under 0.1 and the constraints within 1e-2 (a linear crawl towards the
        optimum, which the exact Hessian finishes in a few dozen iterations)."""
        change = self.cfg.solver.exact_when_stalled
        if change is None:
            return {}
        return {
            "acceptable_iter": 10,
            "acceptable_tol": 0.1,
            "acceptable_constr_viol_tol": 1e-2,
            "acceptable_obj_change_tol": change,
        }

    def _settled_options(self) -> dict:
        """IPOPT's "acceptable" stop for the exact Hessian's solves
        (``SolverCfg.settled_change``): ``settled_iterations`` iterations in a row at a
        feasible point (``constraint_tolerance``) whose objective changes by less than
        ``settled_change`` and whose complementarity is under 1e-9, which a solve reaches
        only once IPOPT has pushed its barrier to the floor (1e-11) without meeting its
        ``tol``. IPOPT's own acceptable level (1e-6) is stricter than that ``tol`` and
        never ends a solve."""
        solver = self.cfg.solver
        if solver.settled_change is None:
            return {}
        return {
            "acceptable_iter": solver.settled_iterations,
            "acceptable_tol": 1.0,
            "acceptable_constr_viol_tol": solver.constraint_tolerance,
            "acceptable_compl_inf_tol": 1e-9,
            "acceptable_obj_change_tol": solver.settled_change,
        }

    def solve(
        self,
        numbers: Numbers | None = None,
        warm_start: Trajectory | None = None,
        pairs: list[CollisionPair] | None = None,
        hessian: str | None = None,
        label: str = "first solve",
    ) -> Trajectory:
        """Solve; a failed solve is a trajectory with ``success`` False, not an exception.

        Args:
            numbers: Other weights, objects' masses, frictions (another grid cell); the
                assembled NLP is reused where the structure is the same.
            warm_start: A solution of the same variables (another cell of a grid, the
                previous round of :mod:`locoman.to.rounds.search`): IPOPT starts from its
                primal-dual point instead of Sec. IV-C.2's guess (from its primal point
                where the constraint rows differ).
            pairs: The collision pairs; default: the configuration's.
            hessian: The Hessian (:data:`locoman.config.to.HESSIANS`) of this solve;
                default: the configuration's, with its switch to the exact one.
            label: What the progress lines call this solve (a round of found pairs).
        """
        numbers = numbers or self.numbers
        # The problem the optimizer was built with, or another one's transcription.
        same = numbers is self.numbers and pairs is None
        tr = self.transcription if same else self.transcribe(numbers, pairs)
        hessian = hessian or self.cfg.solver.hessian
        switch_at = self.switch_at if hessian != "exact" else None
        nlp = self._nlp(tr, hessian)
        inputs = dataclasses.replace(self.inputs, objects=numbers.objects)
        homotopy = self.cfg.collision.homotopy
        layout, schedule, modes = tr.layout, self.schedule, self.modes
        lo, hi = bounds(
            layout,
            inputs,
            schedule,
            modes,
            self.cfg.solver,
            homotopy,
            self.cfg.schedule.end_lift_m,
            self.cfg.contact.slack_max_m,
        )
        X0 = initial_guess(
            layout, inputs, schedule, modes, self.cfg.solver, self.robot.mass, homotopy
        )
        X0 = np.clip(X0, lo, hi).ravel(order="F")
        warm = warm_start.warm_start if warm_start is not None else None
        if warm is not None and warm.lam_g.shape != (nlp.n_g,):
            # More constraint rows (pairs found under a hard treatment): the rows it shares
            # keep their multipliers, the new ones start at 0; without a record of its
            # rows, its primal point only.
            warm = carried_multipliers(warm, tr.blocks, nlp.n_g)
            if warm is None:
                X0 = np.clip(warm_start.warm_start.x, lo.ravel(order="F"), hi.ravel(order="F"))
        p = parameter_vector(tr.blocks)
        args = (X0, lo.ravel(order="F"), hi.ravel(order="F"), p)
        result = nlp.solve(*args, warm, label=f"{label}, {hessian.replace('_', '-')} Hessian")
        stalled = result.status == "Solved_To_Acceptable_Level"
        if switch_at is None or (not stalled and (result.success or result.iterations < switch_at)):
            return self._trajectory(result, tr, nlp, hessian)
        # The first Hessian used its share of the iterations without converging, or stalled:
        # the exact one goes on from its primal-dual point with what is left.
        limits = {"max_iter": self.cfg.solver.max_iterations - result.iterations}
        if self.cfg.solver.max_wall_time_s is not None:
            limits["max_wall_time"] = max(
                self.cfg.solver.max_wall_time_s - result.solve_time_s, 1.0
            )
        log.info(
            f"not converged after {result.iterations} iterations with the {hessian} "
            f"Hessian ({result.status}): on with the exact one"
        )
        exact = self._nlp(tr, "exact")
        polished = exact.solve(*args, result.warm_start, limits, f"{label}, exact Hessian")
        return self._trajectory(polished, tr, nlp, "exact", before=result)

    def _trajectory(
        self,
        result: NLPResult,
        tr: Transcription,
        nlp: BlockNLP,
        hessian: str,
        before: NLPResult | None = None,
    ) -> Trajectory:
        """The trajectory of ``result``; ``before``: the Gauss-Newton phase it went on from."""
        n, layout = self.schedule.nodes, tr.layout
        Z = result.x.reshape(n, layout.width)

        def part(name: str) -> np.ndarray:
            return Z[:, layout.variables[name]]

        def per_object(quantity: str) -> np.ndarray:
            if not layout.n_objects:  # a scene of fixed objects alone: (n, 0, its size)
                return np.zeros((n, 0, 1 if quantity == "support_slack" else 6))
            return np.stack(
                [Z[:, layout.object_variables(j, quantity)] for j in range(layout.n_objects)],
                axis=1,
            )

        objects = [m.objects for m in self.modes]
        phases = [self.schedule.phase(k).name if k > 0 else "start" for k in range(n)]
        exact_iterations = result.iterations if hessian == "exact" else 0
        return Trajectory(
            status=result.status,
            success=result.success,
            iterations=result.iterations + (before.iterations if before else 0),
            solve_time_s=result.solve_time_s + (before.solve_time_s if before else 0.0),
            build_time_s=self.build_time_s,
            function_time_s=result.function_time_s + (before.function_time_s if before else 0.0),
            exact_iterations=exact_iterations,
            alpha_max=float(part("alpha").max()),
            n_variables=nlp.n_x,
            n_constraints=nlp.n_g,
            max_constraint_violation=result.max_constraint_violation,
            cost=result.cost,
            q=part("q"),
            v=part("v"),
            foot_wrench=part("foot_wrench").reshape(n, 2, 6),
            hand_wrench=part("hand_wrench").reshape(n, 2, 6),
            object_q=per_object("q"),
            object_v=per_object("v"),
            support_wrench=per_object("support_wrench"),
            foot_slack=part("foot_slack"),
            hand_slack=part("hand_slack").reshape(n, 2, 3),
            support_slack=per_object("support_slack")[:, :, 0],
            dt=part("dt")[:, 0],
            feet_contact=np.array([m.feet for m in self.modes]),
            foot_object=np.array(
                [[-1 if j is None else j for j in m.feet_on] for m in self.modes], dtype=int
            ),
            hand_object=np.array(
                [[-1 if j is None else j for j in m.hands] for m in self.modes], dtype=int
            ),
            object_active=np.array(
                [[o.active for o in row] for row in objects], dtype=bool
            ).reshape(n, -1),
            support_kind=np.array(
                [[o.support.name if o.support else "none" for o in row] for row in objects],
                dtype=str,
            ).reshape(n, -1),
            support_base=np.array(
                [[_base_index(o.support) for o in row] for row in objects], dtype=int
            ).reshape(n, -1),
            phase=np.array(phases),
            subtask=np.array([self.schedule.subtask_of(k) for k in range(n)]),
            hand_points=self.inputs.hand_points.copy(),
            collision_pairs=len(tr.pairs),
            warm_start=dataclasses.replace(result.warm_start, rows=row_owners(tr.blocks)),
        )
