"""Identification engine: the linear solver shared by fit, diagnose and the Preisach cross-validation (issue 12)."""

from __future__ import annotations

from .linear import METHODS, LinearSolution, column_scale, solve

__all__ = ["METHODS", "LinearSolution", "column_scale", "solve"]
