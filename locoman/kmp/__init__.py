"""Whole-body trajectory learning (paper B, Sec. III-A): demos -> GMM/GMR -> KMP."""
