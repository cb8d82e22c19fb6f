"""``synptv export``: a rendered dataset in the layouts other PTV codes read.

Modules, one job each: :mod:`~validation.export.source` reads and checks the dataset;
:mod:`~validation.export.images` links, copies or converts its images;
:mod:`~validation.export.openptv` and :mod:`~validation.export.myptv` write each
code's layout with a README of what was guessed; :mod:`~validation.commands.export`
the command line. The layouts are described in docs/export.md.
"""
