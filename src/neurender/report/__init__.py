"""The HTML report (``results/report.html``): every measured table and figure beside the
papers' numbers (``paper_numbers.csv``) and our targets (``targets.csv``)."""
