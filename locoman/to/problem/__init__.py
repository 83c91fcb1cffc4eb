"""The TO's problem description: what it reads from the artifacts (:mod:`.loading`) into
its inputs (:mod:`.inputs`), the objects (:mod:`.objects`), the contact schedule
(:mod:`.schedule`) and each node's contact modes (:mod:`.modes`), where each variable and
number sits in a node (:mod:`.layout`), and the numbers per node and per problem
(:mod:`.numbers`). Paper A, Sec. IV-A."""
