"""Identification: stage 1 (``nonlinear``: h and the backlash borders from staircases, Section 4) and
stage 2 (``linear``: G from sines, Section 5), the whole fit (``whole``), and the one path every
entry point takes (``path``).

The package is also callable: ``hwid.identify(data, **options)`` is :func:`hwid.api.identify`
(:mod:`hwid.apinames`).
"""
from hwid.apinames import callable_as

callable_as(__name__, "identify")
