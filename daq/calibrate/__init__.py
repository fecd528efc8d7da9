"""``portal-daq calibrate``: per-leg gain and offset from recordings (see estimator.calibration)."""
