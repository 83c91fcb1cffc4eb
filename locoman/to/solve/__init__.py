"""Solving the TO: the optimiser and its phases (:mod:`.optimizer`), the initial guess
from the keyframes (:mod:`.initial_guess`, Sec. IV-C.2), the variables' bounds
(:mod:`.bounds`) and the solution (:mod:`.trajectory`)."""
