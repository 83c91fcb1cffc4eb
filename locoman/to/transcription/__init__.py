"""The transcription: the problem as data, which kind is called at which node on which
variables with which numbers (:mod:`.transcribe`), through an index of the variables
(:mod:`.index`) and a builder of blocks (:mod:`.builder`), one module per group of rows:
the physics (kinematics, dynamics, contacts, wrenches; :mod:`.physics`), the costs
(:mod:`.objective`) and the collision pairs (:mod:`.collision_rows`)."""
