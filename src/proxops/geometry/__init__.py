"""Polytopes and support functions shared by reach, cortex and hybrid."""
