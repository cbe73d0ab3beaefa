"""What the plotting scripts share: matplotlib without a display, and a CSV
file's rows as dictionaries. `import plot_csv` from a script in this
folder (Python puts a script's own folder on its path)."""
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401


def rows(path):
    """The rows of the CSV file at `path`, each a dict by column name."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))
