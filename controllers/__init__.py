"""Turntable controllers (feed-forward, fuzzy step-count, scan-mode PID): observation → action.

Populated by the controller issue; the thesis (§5.2) asks for a feed-forward and a fuzzy controller.
"""
