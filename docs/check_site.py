"""Look at the documentation site as a reader does, in a real browser, and fail on what is wrong.

Run from the repository root, with the ``docs`` extra installed::

    python docs/check_site.py                    # build the site into a temporary folder
    python docs/check_site.py --site SITE/html   # check a site built already
    python docs/check_site.py --shots shots/     # keep the screenshots there

It builds the site (``sphinx -W``, running every gallery example again), takes full-page
screenshots (PNG) of the index, one API page and every gallery page with headless Chromium,
and checks:

* **overflow**: no code or output block (``pre``, ``div.highlight``) is larger than its box
  and no page is wider than the window (1280 px unless ``--width``), so nothing is cut off on
  the right or at the bottom behind a scroll bar; measured in Chromium by a script added to
  a copy of each page;
* **reprs**: no stray ``<Figure size 640x400 with 1 Axes>`` (or other matplotlib object)
  block in a gallery page;
* **figures**: every log axis of every figure the gallery scripts draw has tick labels, none
  reads like ``8.9x10^1``, and nothing (a legend outside the axes, a label) is drawn beyond a
  figure's edges, where the gallery's image cuts it off (the scripts run again under
  matplotlib's Agg backend; ``--figures-only`` runs just this check);
* **index**: the index page shows a figure and links to the tutorial.

Each problem is one line on stdout; the exit status is 1 when there is any, 0 otherwise.
Without Chromium (``chromium`` or ``chromium-browser`` on the PATH) the browser checks and the
screenshots are skipped with a note, and the others still run.  The static checks are
importable (``check_reprs``, ``check_index``) for the test suite.
"""

from __future__ import annotations

import argparse
import html
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from html.parser import HTMLParser
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
GALLERY = ROOT / "examples" / "gallery"
API_PAGE = "api/generated/flexid.identify.html"  # the page a new user opens first
TUTORIAL = "guide/tutorial.html"
MARK = "flexid-site-check"

# Added before </body> of a copy of each page: measures every code block and the page at the
# window's width, and writes the result into the DOM, where --dump-dom finds it.
PROBE = """
<script>
(function () {
  function measure() {
    var out = {page: [document.documentElement.scrollWidth, window.innerWidth],
               height: document.documentElement.scrollHeight, blocks: []};
    document.querySelectorAll("pre, div.highlight").forEach(function (el) {
      var right = el.scrollWidth > el.clientWidth + 1 && el.clientWidth > 0;
      var bottom = el.scrollHeight > el.clientHeight + 1 && el.clientHeight > 0;
      if (right || bottom) {
        var where = el.closest(".sphx-glr-script-out") ? "output" : "code";
        var lines = (el.textContent || "").split("\\n");
        var line = right ? lines.reduce(function (a, b) {
          return b.length > a.length ? b : a; }, "") : lines[0];
        out.blocks.push({where: where, right: right, bottom: bottom,
                         width: [el.scrollWidth, el.clientWidth],
                         height: [el.scrollHeight, el.clientHeight],
                         line: line.trim().slice(0, 80)});
      }
    });
    var node = document.getElementById("MARK_ID");
    if (!node) {
      node = document.createElement("div");
      node.hidden = true;
      node.id = "MARK_ID";
      document.body.appendChild(node);
    }
    node.textContent = JSON.stringify(out);
  }
  measure();
  window.addEventListener("load", measure);
})();
</script>
""".replace("MARK_ID", MARK)


# ============================================================================ build
def build(outdir: Path, *, rerun_gallery: bool = True) -> list[str]:
    """Build the HTML site into ``outdir`` as CI does; the problems (a failed build)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    if rerun_gallery:
        env["FLEXID_DOCS_RERUN_GALLERY"] = "1"
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
           str(DOCS), str(outdir)]
    print("building the site:", " ".join(cmd), file=sys.stderr)
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    sys.stderr.write(proc.stderr[-4000:])
    if proc.returncode:
        return [f"build: sphinx -W failed (exit {proc.returncode}); see the warnings above"]
    return []


def pages(site: Path) -> list[str]:
    """The pages to look at: the index, one API page, the gallery's index and examples."""
    out = ["index.html"]
    if (site / API_PAGE).is_file():
        out.append(API_PAGE)
    out += sorted(
        p.relative_to(site).as_posix() for p in (site / "auto_examples").glob("*.html")
    )
    return out


# ============================================================================ static checks
class _Links(HTMLParser):
    """The images and links inside the page's <article> (the page's own content)."""

    def __init__(self):
        super().__init__()
        self.depth = 0
        self.images: list[str] = []
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag == "article":
            self.depth += 1
        elif self.depth and tag == "img":
            self.images.append(dict(attrs).get("src") or "")
        elif self.depth and tag == "a":
            self.links.append(dict(attrs).get("href") or "")

    def handle_endtag(self, tag):
        if tag == "article" and self.depth:
            self.depth -= 1


def check_index(site: Path) -> list[str]:
    """The index page shows a figure (an image that exists) and links to the tutorial."""
    page = site / "index.html"
    if not page.is_file():
        return ["index.html: missing"]
    parser = _Links()
    parser.feed(page.read_text(encoding="utf-8"))
    problems = []
    images = [src for src in parser.images if src and (site / src.split("#")[0]).is_file()]
    if not images:
        problems.append("index.html: no figure (no <img> in the page's content that exists)")
    if not any(href.split("#")[0] == TUTORIAL for href in parser.links):
        problems.append(f"index.html: no link to the tutorial ({TUTORIAL})")
    return problems


_REPR = re.compile(r"&lt;(Figure size [^&]*|matplotlib\.[\w.]+ object at 0x[0-9a-f]+)&gt;")


def check_reprs(site: Path) -> list[str]:
    """No gallery page shows ``<Figure size ...>`` or another matplotlib object's repr."""
    problems = []
    for page in sorted((site / "auto_examples").glob("*.html")):
        found = _REPR.findall(page.read_text(encoding="utf-8"))
        if found:
            shown = html.unescape(found[0]).split(" at 0x")[0]
            shown += " at 0x...>" if shown.startswith("matplotlib.") else ">"
            problems.append(
                f"auto_examples/{page.name}: {len(found)} stray output block(s) "
                f"'<{shown}' after a figure"
            )
    return problems


# ============================================================================ the figures
# Run in a fresh interpreter per script: the gallery script draws its figures under Agg, then
# every log axis of every open figure is read back as the reader sees it.
_TICKS = r"""
import json, runpy, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
plt.show = lambda *a, **k: None
runpy.run_path(sys.argv[1], run_name="__main__")
out = []
for num in plt.get_fignums():
    fig = plt.figure(num)
    if sys.argv[2]:  # saved as sphinx-gallery saves it: the figure's box, no tight bbox
        fig.savefig(f"{sys.argv[2]}/{sys.argv[3]}_{num:02d}.png")
    fig.canvas.draw()
    # what lies outside the figure's box is cut off in the gallery's image
    inner, drawn = fig.bbox, fig.get_tightbbox().transformed(fig.dpi_scale_trans)
    cut = {side: round(px) for side, px in (
        ("left", inner.x0 - drawn.x0), ("right", drawn.x1 - inner.x1),
        ("bottom", inner.y0 - drawn.y0), ("top", drawn.y1 - inner.y1)) if px > 0.5}
    if cut:
        out.append({"figure": num, "cut": cut, "title": fig.get_suptitle()
                    or (fig.axes[0].get_title() if fig.axes else "")})
    for k, ax in enumerate(fig.axes):
        if not ax.get_visible():
            continue
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if axis.get_scale() != "log":
                continue
            lo, hi = sorted(axis.get_view_interval())
            labels = []
            for which in ("major", "minor"):
                locs = [x for x in (axis.get_majorticklocs() if which == "major"
                                    else axis.get_minorticklocs())
                        if lo * (1 - 1e-9) <= x <= hi * (1 + 1e-9)]
                fmt = (axis.get_major_formatter() if which == "major"
                       else axis.get_minor_formatter())
                fmt.set_locs(locs)
                labels += [fmt(x, i) for i, x in enumerate(locs)]
            labels = [s for s in labels if s]
            out.append({"figure": num, "axes": k, "title": ax.get_title() or fig.get_suptitle(),
                        "axis": name, "labels": labels})
print(json.dumps(out))
"""


def check_figures(scripts: list[Path], save: Path | None = None) -> list[str]:
    """Every log axis the gallery draws has tick labels, none in the form ``8.9x10^1``, and
    nothing (a legend, a label) is drawn outside a figure, where the gallery's image cuts it.

    With ``save``, the figures are written there as PNG files too, as the gallery saves them.
    """
    problems = []
    env = dict(os.environ, MPLBACKEND="Agg")
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
    for script in scripts:
        with tempfile.TemporaryDirectory() as cwd:  # a script that writes files writes there
            proc = subprocess.run(
                [sys.executable, "-c", _TICKS, str(script), str(save or ""), script.stem],
                cwd=cwd, env=env, capture_output=True, text=True)
        name = script.relative_to(ROOT).as_posix() if script.is_relative_to(ROOT) else script
        if proc.returncode:
            tail = proc.stderr.strip().splitlines()[-1:] or ["?"]
            problems.append(f"{name}: the script failed: {tail[0]}")
            continue
        for axis in json.loads(proc.stdout.strip().splitlines()[-1]):
            if "cut" in axis:
                sides = ", ".join(f"{px} px {side}" for side, px in axis["cut"].items())
                problems.append(f"{name}: figure {axis['figure']} ({axis['title'][:50]!r}) is "
                                f"drawn beyond its edges ({sides}): cut off in the gallery")
                continue
            where = (f"{name}: figure {axis['figure']}, axes {axis['axes']} "
                     f"({axis['title'][:50]!r}), {axis['axis']} axis (log)")
            sci = [s for s in axis["labels"] if "\\times" in s]
            if sci:
                shown = re.sub(r"[{}$]|\\mathdefault", "", sci[0]).replace("\\times", "x")
                problems.append(f"{where}: tick labels in scientific form, e.g. {shown}")
            elif not axis["labels"]:
                problems.append(f"{where}: no tick label")
    return problems


# ============================================================================ browser
def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def _run_chromium(exe: str, profile: Path, args: list[str]) -> subprocess.CompletedProcess:
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           "--no-first-run", "--disable-extensions", "--mute-audio",
           f"--user-data-dir={profile}", "--virtual-time-budget=4000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180)


def check_in_browser(site: Path, names: list[str], shots: Path, width: int) -> list[str]:
    """Screenshots of every page, and the overflow of its code blocks measured in Chromium."""
    exe = _chromium()
    if exe is None:
        print("note: no chromium on the PATH: no screenshots, overflow not checked",
              file=sys.stderr)
        return []
    problems = []
    shots.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as profile:
        for name in names:
            page = site / name
            text = page.read_text(encoding="utf-8")
            probe = page.with_name(f"_{MARK}_{page.name}")  # beside it: same relative links
            probe.write_text(text.replace("</body>", PROBE + "</body>", 1), encoding="utf-8")
            try:
                proc = _run_chromium(exe, Path(profile), [
                    f"--window-size={width},900", "--dump-dom", probe.as_uri()])
            finally:
                probe.unlink()
            found = re.search(
                rf'<div hidden="" id="{MARK}">(.*?)</div>', proc.stdout,
                re.S)
            if not found:
                problems.append(f"{name}: Chromium did not run the page's measurement")
                continue
            result = json.loads(html.unescape(found.group(1)))
            scroll, inner = result["page"]
            if scroll > inner + 1:
                problems.append(f"{name}: the page is {scroll} px wide in a {inner} px window")
            seen = set()
            for block in result["blocks"]:
                for side, key in (("right", "width"), ("bottom", "height")):
                    if not block[side] or (block["line"], side) in seen:
                        continue  # (the <pre> inside its div.highlight counts once)
                    seen.add((block["line"], side))
                    full, shown = block[key]
                    problems.append(
                        f"{name}: {block['where']} block cut off at the {side} ({full} px in "
                        f"{shown} px, behind a scroll bar): {block['line']!r}"
                    )
            height = min(max(int(result["height"]), 600), 16000)
            png = shots / (name.replace("/", "_").removesuffix(".html") + ".png")
            _run_chromium(exe, Path(profile), [
                f"--window-size={width},{height}", f"--screenshot={png}", page.as_uri()])
            if not png.is_file():
                problems.append(f"{name}: no screenshot")
    return problems


# ============================================================================ main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--site", type=Path,
                        help="a built HTML site to check (default: build one into a temporary "
                             "folder)")
    parser.add_argument("--shots", type=Path,
                        help="folder for the screenshots (default: a temporary folder, kept)")
    parser.add_argument("--width", type=int, default=1280,
                        help="browser window width in px (default 1280)")
    parser.add_argument("--cached-gallery", action="store_true",
                        help="when building, let sphinx-gallery skip examples whose script did "
                             "not change (faster; figures may be stale)")
    parser.add_argument("--no-figures", action="store_true",
                        help="do not run the gallery scripts to check their figures")
    parser.add_argument("--figures-only", action="store_true",
                        help="only run the gallery scripts and check their figures (no build, "
                             "no browser)")
    parser.add_argument("--save-figures", type=Path,
                        help="also write the gallery's figures there (PNG, as the gallery "
                             "saves them)")
    args = parser.parse_args(argv)

    problems: list[str] = []
    scripts = sorted(GALLERY.glob("plot_*.py"))
    if args.figures_only:
        problems = check_figures(scripts, args.save_figures)
        for line in problems:
            print(line)
        return 1 if problems else 0
    tmp = None
    site = args.site
    if site is None:
        tmp = Path(tempfile.mkdtemp(prefix="flexid-site-"))
        site = tmp / "html"
        problems += build(site, rerun_gallery=not args.cached_gallery)
    site = site.resolve()
    if not (site / "index.html").is_file():
        problems.append(f"{site}: no index.html (not a built site)")
    else:
        problems += check_index(site)
        problems += check_reprs(site)
        shots = args.shots or Path(tempfile.mkdtemp(prefix="flexid-shots-"))
        problems += check_in_browser(site, pages(site), shots.resolve(), args.width)
        if _chromium():
            print(f"screenshots in {shots.resolve()}", file=sys.stderr)
    if not args.no_figures:
        problems += check_figures(scripts, args.save_figures)
    if tmp is not None:
        print(f"site in {site}", file=sys.stderr)
    print(f"{len(problems)} problem(s)", file=sys.stderr, flush=True)
    for line in problems:
        print(line)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
