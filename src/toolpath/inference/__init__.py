"""Deployment of the trained classifiers (Sec. 5.1.2, Table 4): quantization-aware training to INT8
(:mod:`~toolpath.inference.qat`), the ONNX runtimes it ships for (:mod:`~toolpath.inference.runtimes`) and
honest inference timing (:mod:`~toolpath.inference.timing`).  Used by the ``qat`` and ``benchmark`` stages
and by ``toolpath smooth --classifier``."""
