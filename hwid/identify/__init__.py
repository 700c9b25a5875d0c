"""Identification: stage 1 (``nonlinear``: h and the backlash borders from staircases, Section 4) and
stage 2 (``linear``: G from sines, Section 5)."""
