"""Regenerate docs/img/replay.png: the demo's replay in Debian's chromium, paused in its crossing.

    python docs/screenshot.py [--chromium /usr/bin/chromium] [--out docs/img/replay.png]
    python docs/screenshot.py --task examples/cell_torch_program.yaml --out docs/img/cell_replay.png

With ``--task`` the task is planned instead of the demo and the replay is paused at its closest
approach (its collision check's), or in its first crossing when it has none.

Needs the test extra (Playwright's Python package) and the Debian ``chromium`` package; no
browser is downloaded.
"""

from __future__ import annotations

import argparse
import struct
import sys
import tempfile
import zlib
from pathlib import Path

from singplan.cli import main as singplan_main
from singplan.results.trajectory import load

HERE = Path(__file__).resolve().parent
FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--use-gl=swiftshader", "--enable-unsafe-swiftshader"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--out", type=Path, default=HERE / "img" / "replay.png")
    parser.add_argument("--task", type=Path, default=None, help="plan this task instead of the demo")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "demo"
        command = ["plan", str(args.task), "-o", str(out), "--quiet"] if args.task else ["demo", "-o", str(out)]
        if singplan_main(command) != 0:
            return 1
        traj = load(out)
        crossing = next((s for s in traj.segments if s.kind == "crossing"), None)
        clearance = traj.metrics.clearance
        if args.task and clearance is not None and clearance.min_clearance_t is not None:
            at = clearance.min_clearance_t
        elif crossing is not None:
            at = 0.5 * (crossing.t0 + crossing.t1)
        else:
            at = 0.5 * traj.duration_s
        from playwright.sync_api import sync_playwright  # the test extra's; png_text needs none of it

        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=args.chromium, headless=True, args=FLAGS)
            page = browser.new_page(viewport={"width": 1200, "height": 760})
            page.goto((out / "replay.html").as_uri())
            page.wait_for_function("window.singplan && window.singplan.ready", timeout=60_000)
            page.evaluate("(t) => window.singplan.seek(t)", at)
            page.wait_for_timeout(500)
            args.out.parent.mkdir(parents=True, exist_ok=True)
            png = page.screenshot()
            browser.close()
        duration_s = traj.duration_s
    args.out.write_bytes(with_text(png, DURATION_KEY, f"{duration_s:.3f}"))
    print(f"wrote {args.out}")
    return 0


DURATION_KEY = "singplan demo duration_s"  # tests/test_docs_harness.py compares it with the demo planned now


def with_text(png: bytes, key: str, value: str) -> bytes:
    """The PNG with a tEXt chunk ``key``: ``value`` after its header chunk (PNG 1.2, section 11.3.4.3)."""
    data = key.encode("latin-1") + b"\0" + value.encode("latin-1")
    chunk = struct.pack(">I", len(data)) + b"tEXt" + data + struct.pack(">I", zlib.crc32(b"tEXt" + data))
    end_of_header = 8 + 4 + 4 + 13 + 4  # signature, IHDR length, type, data, CRC
    return png[:end_of_header] + chunk + png[end_of_header:]


def png_text(png: bytes) -> dict[str, str]:
    """The tEXt chunks of a PNG."""
    out, at = {}, 8
    while at < len(png):
        length, kind = struct.unpack(">I4s", png[at:at + 8])
        if kind == b"tEXt":
            key, _, value = png[at + 8:at + 8 + length].partition(b"\0")
            out[key.decode("latin-1")] = value.decode("latin-1")
        at += 12 + length
    return out


if __name__ == "__main__":
    sys.exit(main())
