"""One thin module per DVC stage: the only code that reads and writes pipeline files and tracks runs."""

from toolpath.pipeline.warm import hand_over_stage

# under `make repro`'s warm server the stage runs there (its libraries already imported) and this process
# exits with its status; otherwise it runs here
hand_over_stage()
