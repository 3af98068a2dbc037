# %% [markdown]
# # Share a run
#
# A run of tileviz studied in a notebook (or run as a script: `python examples/share_a_run.py
# [DATASET] [OUT_DIR]`). Without a dataset it records a short one first. Open it in Jupyter as
# a notebook with jupytext, or paste the cells: `tileviz.show` then draws the page inline.

# %%
import sys
from pathlib import Path

import tileviz
from tileviz.share.figure import save_figure
from tileviz.share.page import PageOptions, export_html, page_views
from tileviz.share.run import load_run


def main(argv: list[str]) -> None:
    out = Path(argv[1] if len(argv) > 1 else "out/share")
    out.mkdir(parents=True, exist_ok=True)
    dataset = Path(argv[0]) if argv else out / "run"
    if not dataset.exists():  # a 3 s run of the simulator
        from tileviz.cli import record

        record([str(dataset), "--duration", "3", "--quiet"])

    # %% the per-frame records: a pandas DataFrame when pandas is installed, else dicts
    table = tileviz.replay(dataset)
    rows = table.to_dict("records") if hasattr(table, "to_dict") else table
    widths = [100 * (r["x_hi"] - r["x_lo"]) for r in rows]
    inside = sum(1 for r in rows if r["inside"])
    print(f"{len(rows)} frames; set width in x {min(widths):.2f} to {max(widths):.2f} cm; "
          f"truth inside the set at {inside} frames")

    # %% the figure and the page (in Jupyter: tileviz.show(dataset) draws the page inline)
    opts = PageOptions(every=2)
    run = load_run(dataset, views=page_views(opts))
    print("figure:", save_figure(run, out / "run.png", every=10))
    print("page:", export_html(run, out / "run.html", opts))
    if "ipykernel" in sys.modules:
        tileviz.show(dataset, every=2)


if __name__ == "__main__":
    main(sys.argv[1:])
