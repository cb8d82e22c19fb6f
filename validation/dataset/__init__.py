"""Dataset folders: rendering one (``synptv render``), its truth file, calibrating its
cameras (``synptv calibrate``)."""
