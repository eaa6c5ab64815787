"""Stress tests of numerical stability: families of hard cases, each run by every solver that applies."""

from .families import FAMILIES, FAMILY_TITLES, StressCase, cases
from .report import StressReport, StressRow, stress, write_report

__all__ = ["FAMILIES", "FAMILY_TITLES", "StressCase", "cases", "StressReport", "StressRow", "stress",
           "write_report"]
