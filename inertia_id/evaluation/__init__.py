"""Trained classifiers at work: telemetry, identification, noise sweeps and the HTML report."""
