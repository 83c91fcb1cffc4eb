"""The NLP the transcription becomes, and IPOPT on it: the terms compiled to C once per
robot (:mod:`.compile`, :mod:`.derivatives`), the sparsity and oracles f, g and their
derivatives evaluated from the compiled terms (:mod:`.sparsity`, :mod:`.oracle_state`,
:mod:`.oracles`, :mod:`.convexify`, :mod:`.callback`), the IPOPT problem (:mod:`.ipopt`),
the multipliers carried from one solve to the next (:mod:`.multipliers`) and the progress
line (:mod:`.progress`)."""
