"""The virtual laboratory's ground truth: flow, particles, optics and rendering.

``simulator`` imports neither ``ptv`` nor ``validation``.
"""
