"""What the truth says: the sample-truth and exact statistics of the flow, the errors of
a calibration, the quality of a matching."""
