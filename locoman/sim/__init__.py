"""MuJoCo evaluation of solved trajectories (paper A, Sec. V)."""
