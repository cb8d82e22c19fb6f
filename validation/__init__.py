"""Where truth and estimate meet: scenarios, experiments, claims, studies, reports, CLI."""
