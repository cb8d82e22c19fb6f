"""How the work runs: workers, reusable stages, chunks kept on disk, whole files, locks,
progress."""
