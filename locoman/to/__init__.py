"""Paper A's whole-body trajectory optimisation (Sec. IV), one way through its folders:

problem description (:mod:`.problem`) -> transcription (:mod:`.transcription`) -> compiled
terms (:mod:`.terms`, with the collision geometry of :mod:`.collisions`) -> NLP
(:mod:`.nlp`) -> optimiser (:mod:`.solve`) -> rounds of found pairs (:mod:`.rounds`) ->
trajectory (:mod:`.pipeline` writes it, :mod:`.io` names its fields).

docs/trajectory-optimisation.md maps each of the paper's equations to its file.
"""
