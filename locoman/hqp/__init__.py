"""Hierarchical QP whole-body control of the mobile manipulator (paper B, Sec. III-B, III-C)."""
