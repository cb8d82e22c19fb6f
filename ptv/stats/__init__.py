"""Statistics of measured displacements: pair binning, multi-Δt fits, S2 and ε; and of
tracks: Lagrangian statistics with the noise removed over several steps
(:mod:`ptv.stats.lagrangian`)."""
