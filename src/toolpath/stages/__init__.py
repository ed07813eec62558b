"""One thin module per DVC stage: the only code that reads and writes pipeline files and tracks runs."""
