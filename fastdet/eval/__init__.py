"""Scoring boxes against ground truth: matching, precision / recall / F1 / AP, MOT metrics
(:mod:`.metrics`); the table and the PR plot (:mod:`.report`)."""
from .metrics import EvalResult, average_precision, evaluate, frame_counts, match_frame, precision_envelope
from .report import format_table, plot_pr

__all__ = ["EvalResult", "average_precision", "evaluate", "frame_counts", "match_frame", "precision_envelope",
           "format_table", "plot_pr"]
