"""The HTML report (``results/report.html``): every measured table and figure beside the
papers' numbers and our targets (each method's tables: :meth:`neurender.method.Method.table`)."""
