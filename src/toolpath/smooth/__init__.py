"""``toolpath smooth``, the product: a rough G-code program in, a smoother one out, within a two-sided
tolerance and with nothing else changed (Sec. 5.3 on a whole program).

It owns the command line (:mod:`~toolpath.smooth.command`), the rewrite of moved lines
(:mod:`~toolpath.smooth.rewrite`), streaming of long programs (:mod:`~toolpath.smooth.stream`), arc
welding (:mod:`~toolpath.smooth.arc_weld`) and its JSON / HTML report (:mod:`~toolpath.smooth.report`).
It needs only the core install (NumPy and rich); a trained ``.pt`` classifier needs the ``[models]``
extra, an ``.onnx`` one the ``[int8]`` extra.  No pipeline stage imports it: a change here leaves
``dvc status`` up to date.
"""
