// The viewer page as a person sees it at 1280 x 800 in headless Chromium (Debian's, through
// playwright-core in tools/node), for tests/test_viewer.py.
// Usage: node tools/browser_layout.js URL OUT_DIR
//   writes OUT_DIR/window.png (what fits in the window), OUT_DIR/page.png (the whole page) and
//   OUT_DIR/report.json: the viewport, where the face and the video lie, whether the play controls
//   show, each curve chart's name, unit, note and tick labels, and, for a model with AU sliders, the
//   sliders and morph influences as loaded; where the model carries a recipe, also after its first
//   unit is raised by 0.2 (OUT_DIR/adjusted.png), put back (restored.png, beside recipe.png), and after
//   every unit of the recipe is set to 0.
const path = require('path');
const { withViewerPage } = require('./viewer_page');

(async () => {
  const [url, out] = process.argv.slice(2);
  await withViewerPage(url, out, { width: 1280, height: 800 }, async (page, report) => {
    await page.waitForTimeout(500);
    await page.screenshot({ path: path.join(out, 'window.png') });
    Object.assign(report, await page.evaluate(() => {
      const rect = (el) => {
        if (!el || !el.checkVisibility()) return null;
        const r = el.getBoundingClientRect();
        return { left: r.left, top: r.top, right: r.right, bottom: r.bottom };
      };
      const text = (el) => (el ? el.textContent : null);
      return {
        viewport: { width: window.innerWidth, height: window.innerHeight },
        face: rect(document.getElementById('face')),
        video: rect(document.getElementById('source')),
        transport: rect(document.getElementById('transport')),
        charts: [...document.querySelectorAll('.chart')].map((c) => ({
          name: c.dataset.group,
          unit: text(c.querySelector('.unit')),
          note: text(c.querySelector('.note')),
          y_ticks: [...c.querySelectorAll('text.tick.y')].map(text),
          x_ticks: [...c.querySelectorAll('text.tick.x')].map(text),
          curves: c.querySelectorAll('path').length,
        })),
        editor: !document.getElementById('editor').hidden,
      };
    }));
    report.notes_visible = [];
    for (const note of await page.locator('.chart .note').all()) {
      await note.scrollIntoViewIfNeeded();
      report.notes_visible.push(await note.isVisible());
    }
    if (report.editor) {
      const face = page.locator('#face');
      await face.scrollIntoViewIfNeeded();
      report.units = await page.evaluate(() => window.viewer.units());
      report.influences = await page.evaluate(() => window.viewer.influences());
      report.recipe = await page.evaluate(() => window.viewer.recipe());
      const first = Object.keys(report.units).find((name) => report.units[name] > 0);
      if (first) {
        const set = (name, value) => page.evaluate(([n, v]) => window.viewer.setUnit(n, v), [name, value]);
        await face.screenshot({ path: path.join(out, 'recipe.png') });
        report.adjusted_unit = first;
        await set(first, report.units[first] + 0.2);
        await page.waitForTimeout(200);
        await face.screenshot({ path: path.join(out, 'adjusted.png') });
        report.adjusted = { recipe: await page.evaluate(() => window.viewer.recipe()),
          influences: await page.evaluate(() => window.viewer.influences()) };
        await set(first, report.units[first]);
        await page.waitForTimeout(200);
        await face.screenshot({ path: path.join(out, 'restored.png') });
        for (const [name, value] of Object.entries(report.units)) if (value > 0) await set(name, 0);
        report.zeroed = { recipe: await page.evaluate(() => window.viewer.recipe()),
          influences: await page.evaluate(() => window.viewer.influences()) };
      }
    }
    report.page_errors = await page.evaluate(() => window.viewer.errors);
    await page.screenshot({ path: path.join(out, 'page.png'), fullPage: true });
  });
})().catch((e) => { console.error(String(e)); process.exit(1); });
