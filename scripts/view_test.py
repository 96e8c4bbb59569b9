#!/usr/bin/env python3
"""`tstat view` in a real browser: headless Chromium from the distribution's packages,
driven by Playwright.

    python3 scripts/view_test.py [--out docs/view]

Set-up (not CI): `apt-get install -y chromium` and `pip install playwright` (the Python
package only: the test uses the system's /usr/bin/chromium, so no browser download).

It renders cbox (64x64, 150 bins of 0.08 OPL, 16 spp), denoises it, and writes a page
with the denoised volume and a reference (a 1024-spp render); a second page from a
bundle rendered with `--transform box-cox:0.5` (no band), a third with a tiny
`--max-bytes` (block-averaged), and two of an adaptive render (whole and
block-averaged; the notes must say the band uses each pixel's own count). For each
page it checks, in the browser:

- no console errors or page errors while loading and interacting;
- the page opens still (the play button says "play", the slider at bin 0);
- the time slider, moved with the keyboard, changes the time label and the image;
- every image panel is non-blank at a bin where light has arrived;
- clicking a pixel on the noisy panel draws the transient plot (pixels in each
  channel's colour), the confidence band (translucent fill) when the bundle has V,
  the membership map (green and red cells), and the G-buffer table;
- play starts playback (the bin advances) and pause stops it.

Screenshots of the first page (opened; slider moved and pixel clicked) go to --out.
Prints PASS or exits non-zero with what failed.
"""
import argparse
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSTAT = os.path.join(ROOT, "target", "release", "tstat")
SCENE = os.path.join(ROOT, "scenes", "cbox.xml")
FILM = ["--width", "64", "--bins", "150", "--bin-width-opl", "0.08"]


def run(*args):
    r = subprocess.run([TSTAT, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"tstat {' '.join(args)} failed:\n{r.stderr}")
    return r.stdout + r.stderr


# Colour statistics of a canvas, computed in the page.
CANVAS_STATS = """(id) => {
  const cv = typeof id === 'string' ? document.getElementById(id) : id;
  const d = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data;
  let lit = 0, red = 0, green = 0, blue = 0, translucent = 0, cellsGreen = 0, cellsRed = 0;
  for (let i = 0; i < d.length; i += 4) {
    const [r, g, b, a] = [d[i], d[i+1], d[i+2], d[i+3]];
    if (a > 0 && (r > 8 || g > 8 || b > 8)) lit++;
    if (a > 100 && r > 150 && g < 90 && b < 90) red++;
    if (a > 100 && g > 120 && r < 90 && b < 90) green++;
    if (a > 100 && b > 130 && r < 90 && g < 160) blue++;
    if (a > 0 && a < 255) translucent++;
    if (r === 44 && g === 160 && b === 44) cellsGreen++;
    if (r === 214 && g === 39 && b === 40) cellsRed++;
  }
  return {lit, red, green, blue, translucent, cellsGreen, cellsRed, total: d.length / 4};
}"""


def check_page(browser, path, expect_band, shots=None):
    failures = []
    page = browser.new_page(viewport={"width": 1300, "height": 900})
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto("file://" + path)
    page.wait_for_load_state("load")
    name = os.path.basename(path)

    def need(cond, what):
        if not cond:
            failures.append(f"{name}: {what}")

    need(page.inner_text("#play") == "play", "the page must open still")
    need(page.input_value("#time") == "0", "the slider starts at bin 0")
    if shots:
        page.screenshot(path=os.path.join(shots, "view_opened.png"), full_page=True)
    label0 = page.inner_text("#timelabel")
    # Move the slider with the keyboard to bin 40 (light has arrived everywhere by then).
    page.focus("#time")
    for _ in range(40):
        page.keyboard.press("ArrowRight")
    need(page.input_value("#time") == "40", f"slider at {page.input_value('#time')} after 40 key presses")
    need(page.inner_text("#timelabel") != label0 and "bin 40" in page.inner_text("#timelabel"),
         "the time label follows the slider")
    panels = page.query_selector_all(".panel canvas")
    need(len(panels) >= 1, "no image panel")
    for i, cv in enumerate(panels):
        st = page.evaluate(CANVAS_STATS, cv)
        need(st["lit"] > 0.2 * st["total"], f"panel {i} is blank at bin 40 ({st['lit']} of {st['total']} lit)")
    # Click a pixel on the noisy panel: the back wall, left of centre.
    box = panels[0].bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.35, box["y"] + box["height"] * 0.45)
    plot = page.evaluate(CANVAS_STATS, "plot")
    need(plot["red"] > 30 and plot["green"] > 30 and plot["blue"] > 30,
         f"the transient curves are not drawn in each channel's colour: {plot}")
    if expect_band:
        need(plot["translucent"] > 200, f"no confidence band drawn: {plot}")
        mem = page.evaluate(CANVAS_STATS, "members")
        need(mem["cellsGreen"] > 0 and mem["cellsRed"] + mem["cellsGreen"] > 50,
             f"membership map not drawn: {mem}")
    else:
        need("No confidence band" in page.inner_text("#notes"), "the page must say it has no band")
    need("albedo" in page.inner_text("#gbuf") and "depth" in page.inner_text("#gbuf"),
         "G-buffer table missing")
    if shots:
        page.screenshot(path=os.path.join(shots, "view_pixel.png"), full_page=True)
    # Playback.
    t0 = int(page.input_value("#time"))
    page.click("#play")
    page.wait_for_timeout(700)
    page.click("#play")
    t1 = int(page.input_value("#time"))
    need(t1 != t0, "play did not advance the bin")
    page.wait_for_timeout(300)
    need(int(page.input_value("#time")) == t1, "pause did not stop playback")
    need(not errors, f"console errors: {errors}")
    page.close()
    return failures


def check_notes(browser, path, want):
    page = browser.new_page()
    page.goto("file://" + path)
    page.wait_for_load_state("load")
    text = page.inner_text("#notes")
    page.close()
    return [] if want in text else [f"{os.path.basename(path)}: the notes lack {want!r}: {text}"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "view"))
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    a = ap.parse_args()
    from playwright.sync_api import sync_playwright

    os.makedirs(a.out, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        p = lambda n: os.path.join(tmp, n)
        run("render", SCENE, *FILM, "--spp", "16", "--seed", "1", "--out", p("b.tstats"))
        run("render", SCENE, *FILM, "--spp", "1024", "--seed", "2", "--out", p("ref.tstats"))
        run("denoise", p("b.tstats"), "--out", p("d.npy"))
        print(run("view", p("b.tstats"), "--denoised", p("d.npy"), "--reference", p("ref.tstats"),
                  "--out", p("full.html")).strip())
        run("render", SCENE, *FILM, "--spp", "16", "--transform", "box-cox:0.5", "--out", p("bc.tstats"))
        print(run("view", p("bc.tstats"), "--out", p("boxcox.html")).strip())
        print(run("view", p("b.tstats"), "--max-bytes", "2M", "--out", p("small.html")).strip())
        # An adaptive bundle: the band takes each pixel's own degrees of freedom, whole
        # and block-averaged.
        run("render", SCENE, *FILM, "--spp", "16", "--adaptive", "--seed", "3", "--out", p("ad.tstats"))
        print(run("view", p("ad.tstats"), "--out", p("adaptive.html")).strip())
        print(run("view", p("ad.tstats"), "--max-bytes", "2M", "--out", p("adaptive_small.html")).strip())
        failures = []
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=a.chromium, args=["--no-sandbox"])
            failures += check_page(browser, p("full.html"), True, shots=a.out)
            failures += check_page(browser, p("boxcox.html"), False)
            failures += check_page(browser, p("small.html"), True)
            for name in ("adaptive.html", "adaptive_small.html"):
                failures += check_page(browser, p(name), True)
                failures += check_notes(browser, p(name), "each pixel's own n samples")
            browser.close()
    for f in failures:
        print("FAIL:", f)
    if failures:
        sys.exit(1)
    print(f"PASS (screenshots in {os.path.relpath(a.out, ROOT)})")


if __name__ == "__main__":
    main()
