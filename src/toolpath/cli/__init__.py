"""Command-line tools around the pipeline (the stages themselves live in :mod:`toolpath.stages`)."""
