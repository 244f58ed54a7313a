"""Reinforcement-learning agents (stable-baselines3) for the turntable environment.

Populated by the RL issue.
"""
