"""Polytopes and support functions shared by reach, cortex and hybrid."""

from proxops.geometry.polytope import ConvexSection, SectionPolygon, row_intervals

__all__ = ["ConvexSection", "SectionPolygon", "row_intervals"]
