"""Where benchmark tables go: printed, and written to ``benchmarks/results/``."""

from __future__ import annotations

from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def publish(name: str, lines: list[str], *, echo: bool = True) -> Path:
    """Write ``lines`` to ``benchmarks/results/<name>`` (and print them); return the path."""
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / name
    path.write_text("\n".join(lines) + "\n")
    if echo:
        print("\n".join(lines))
    return path
