"""A dataset folder's cameras calibrated from its plate images with every method
(``synptv calibrate``); rendering a dataset is :mod:`validation.run.render_dataset`, its
truth file :mod:`validation.truth.truth_file`."""
