"""``synptv export``: a rendered dataset in the layouts other PTV codes read.

Modules, one job each: :mod:`~validation.export.source` reads and checks the dataset;
:mod:`~validation.export.image_copies` links, copies or converts its images;
:mod:`~validation.export.openptv`, :mod:`~validation.export.myptv` and
:mod:`~validation.export.openlpt` (with its cameras,
:mod:`~validation.export.openlpt_cameras`, and the IPR driver script it ships,
:mod:`~validation.export.openlpt_driver`) write each code's layout with a README of what
was guessed; :mod:`~validation.commands.export` the command line. The layouts are
described in docs/export.md.
"""
