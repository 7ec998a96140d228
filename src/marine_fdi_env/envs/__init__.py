"""Gymnasium environment ``MarineFDI-v0`` for fault detection and isolation."""
