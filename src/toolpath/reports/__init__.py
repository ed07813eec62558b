"""Tables and figures from the pipeline's DVC outputs."""
