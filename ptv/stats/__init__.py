"""Statistics of measured displacements: pair binning, multi-Δt fits, S2 and ε."""
