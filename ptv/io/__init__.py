"""A dataset folder as an experiment gives it: ``experiment.json`` checked against its
schema (:mod:`ptv.io.experiment_file`), grey images and masks (:mod:`ptv.io.images`), the
folder's frame pairs (:mod:`ptv.io.dataset`) and a time-resolved recording cut into
pairs (:mod:`ptv.io.sequence`); docs/experiment.md."""
