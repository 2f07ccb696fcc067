"""What every example shares: the command line, the table of the paper's numbers beside the
service's, the figures written to files, and the exit status (0 when every number agrees).

Each example is run as ``python examples/<name>.py [--url URL] [--out DIR]`` against a running
service (the README's first command serves ``http://127.0.0.1:8000``)."""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

from linkage_client import Client


@dataclass
class Row:
    """One number of the paper: what the paper says, what the service answered, whether they
    agree (a checked claim, never a tolerance chosen after the fact)."""

    what: str
    paper: str
    service: str
    agrees: bool


@dataclass
class Report:
    """The rows of one example, printed as a table; :meth:`finish` is the exit status."""

    title: str
    out: Path
    rows: list[Row] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)

    def check(self, what: str, paper: object, service: object, agrees: bool) -> None:
        self.rows.append(Row(what, str(paper), str(service), bool(agrees)))

    def note(self, text: str) -> None:
        self.notes.append(text)

    def figure(self, name: str, svg: str) -> None:
        """Write one figure (SVG text) to ``out/name``."""
        self.out.mkdir(parents=True, exist_ok=True)
        path = self.out / name
        path.write_text(svg)
        self.figures.append(path)

    def finish(self) -> int:
        width = max((len(r.what) for r in self.rows), default=10)
        print(f"# {self.title}\n")
        print(f"{'':2}{'':{width}}  {'paper':<24} service")
        for r in self.rows:
            mark = "ok" if r.agrees else "NO"
            print(f"{mark:2} {r.what:{width}}  {r.paper:<24} {r.service}")
        for text in self.notes:
            print(f"\nnote: {text}")
        for path in self.figures:
            print(f"figure: {path}")
        bad = [r.what for r in self.rows if not r.agrees]
        if bad:
            print(f"\n{len(bad)} of {len(self.rows)} numbers disagree with the paper: {bad}",
                  file=sys.stderr)
        return 1 if bad or not self.rows else 0


def start(title: str, doc: str | None) -> tuple[Client, Report]:
    """The client and the report of one example, from its command line."""
    parser = argparse.ArgumentParser(description=doc)
    parser.add_argument("--url", default="http://127.0.0.1:8000", help="the service")
    parser.add_argument("--out", type=Path, default=Path("figures"),
                        help="where the figures are written (default: ./figures)")
    args = parser.parse_args()
    # searches answer within their own time budgets; the timeout only bounds a lost connection
    return Client(args.url, timeout=180.0), Report(title, args.out)


def sign(x: float) -> str:
    """``+`` or ``-`` (the paper's labels of regions by the signs of tau)."""
    return "+" if x > 0 else "-"
