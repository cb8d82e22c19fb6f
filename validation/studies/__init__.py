"""``synptv study``: parameter sweeps of the calibration and of the multi-Δt method, on
KS particles or through images."""
