"""The kinds of terms paper A's TO is made of, one module per area of the paper, each
with its equations and the compiled kinds built from them: the robot's kinematics
(:mod:`.kinematics`), the dynamics (1) (:mod:`.dynamics`), the contacts (2)-(6)
(:mod:`.contacts`), the supports (7) (:mod:`.supports`), the costs of Table I, (9), (10)
(:mod:`.costs`) and the collisions (11)-(13) (:mod:`.collisions`); the term data model in
:mod:`.term`, the robot's set of kinds in :mod:`.library`."""
