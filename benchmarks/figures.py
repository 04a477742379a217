"""A benchmark's figure written where its table says, and named on the console."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def save_figure(fig: Any, path: Path, dpi: int = 100) -> None:
    """Lay ``fig`` out, write it to ``path`` (folders made), close it and print where it went."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    print(f"\nfigure: {path}")
