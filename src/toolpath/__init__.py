"""toolpath-lab: CNC toolpath roughness recognition and smoothing.

Domain sub-packages (``gcode``, ``geometry``, ``shapes``, ``labels`` ...) take and return arrays and
dataclasses; only ``toolpath.stages`` reads files named in ``params.yaml`` and talks to MLflow.
"""

__version__ = "0.1.0"
