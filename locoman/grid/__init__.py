"""Paper A's ablation grids (Sec. V): Fig. 5 and Fig. 6 as grids of TO cells.

A cell is one solve and evaluation of a scenario: a :class:`~locoman.grid.runs.Run` (which
contacts, which keyframe terms, which collision terms) at one box mass and initial yaw. Cells
reuse the pipeline's upstream artifacts (perception, contacts, keyframes) and rebuild only
the scene, so a grid costs its solves. They run as the jobs of a Hydra multirun
(:mod:`locoman.grid.app`), where the launcher plugin decides where: joblib locally, submitit
on SLURM. :mod:`locoman.grid.figures` draws the figures and the summary from the cells'
records.
"""
