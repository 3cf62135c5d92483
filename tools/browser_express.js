// An animated `faceanim express` model in the viewer (headless Chromium through tools/viewer_page.js), for
// tests/test_viewer.py: the AU sliders adjust the expression's apex and the animation plays it.
// Usage: node tools/browser_express.js URL OUT_DIR [WIDTHxHEIGHT] (default 1280x800)
//   writes OUT_DIR/window.png (the window as loaded), apex.png (after the first recipe unit is raised by
//   0.2: the face paused at the apex), played_a.png and played_b.png (playing the adjusted expression),
//   zeroed.png (every recipe unit at 0, at the apex) and rest.png (at time 0), and OUT_DIR/report.json:
//   the viewport, where the face, the video and the play controls lie, the apex's time, and the time,
//   the clip's strength and the morph influences at each of those moments.
const path = require('path');
const { withViewerPage } = require('./viewer_page');

(async () => {
  const [url, out, size] = process.argv.slice(2);
  const [width, height] = (size || '1280x800').split('x').map(Number);
  await withViewerPage(url, out, { width, height }, async (page, report) => {
    await page.waitForTimeout(300);
    await page.screenshot({ path: path.join(out, 'window.png') });
    Object.assign(report, await page.evaluate(() => {
      const rect = (el) => {
        if (!el || !el.checkVisibility()) return null;
        const r = el.getBoundingClientRect();
        return { left: r.left, top: r.top, right: r.right, bottom: r.bottom };
      };
      return {
        viewport: { width: window.innerWidth, height: window.innerHeight },
        face: rect(document.getElementById('face')),
        video: rect(document.getElementById('source')),
        transport: rect(document.getElementById('transport')),
        editor: !document.getElementById('editor').hidden,
        help: document.getElementById('editor-help').textContent,
        apex: window.viewer.apex,
        duration: window.viewer.duration,
        units: window.viewer.units(),
      };
    }));
    const state = () => page.evaluate(() => ({ time: window.viewer.time, playing: window.viewer.playing,
      strength: window.viewer.strength(), influences: window.viewer.influences(), recipe: window.viewer.recipe() }));
    const set = (name, value) => page.evaluate(([n, v]) => window.viewer.setUnit(n, v), [name, value]);
    const face = page.locator('#face');
    const first = Object.keys(report.units).find((name) => report.units[name] > 0);
    report.adjusted_unit = first;
    await set(first, report.units[first] + 0.2); // while playing: pauses at the apex
    await page.waitForTimeout(200);
    report.at_apex = await state();
    await face.screenshot({ path: path.join(out, 'apex.png') });
    await page.evaluate((t) => window.viewer.seek(t), 0.15 * report.duration); // halfway up the onset
    await page.waitForTimeout(100);
    report.onset = await state();
    await page.evaluate(() => window.viewer.play());
    report.played = [];
    // 12 samples 120 ms apart cover most of the 2 s clip where the page draws at its pace; where it
    // draws slowly (software GL on a loaded machine) the clip's clock moves less per sample, so up to
    // 40 are taken, until the strength has moved through a good part of the clip.
    const spread = () => {
      const s = report.played.map((p) => p.strength);
      return Math.max(...s) - Math.min(...s);
    };
    for (let k = 0; k < 40 && (k < 12 || spread() <= 0.4); k++) {
      await page.waitForTimeout(120);
      report.played.push(await state());
      if (k === 2) await face.screenshot({ path: path.join(out, 'played_a.png') });
      if (k === 8) await face.screenshot({ path: path.join(out, 'played_b.png') });
    }
    for (const [name, value] of Object.entries(report.units)) if (value > 0) await set(name, 0);
    await page.evaluate((t) => window.viewer.seek(t), report.apex);
    await page.waitForTimeout(100);
    report.zeroed = await state();
    await face.screenshot({ path: path.join(out, 'zeroed.png') });
    await page.evaluate(() => window.viewer.seek(0));
    await page.waitForTimeout(100);
    report.rest = await state();
    await face.screenshot({ path: path.join(out, 'rest.png') });
    report.page_errors = await page.evaluate(() => window.viewer.errors);
  });
})().catch((e) => { console.error(String(e)); process.exit(1); });
