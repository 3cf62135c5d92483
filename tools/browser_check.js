// Drive the viewer page in headless Chromium (Debian's, through playwright-core in tools/node) and
// report what a person would see, for tests/test_viewer.py.
// Usage: node tools/browser_check.js URL OUT_DIR [AU_NAME]
//   writes OUT_DIR/playing_a.png, playing_b.png (the face 1.5 s apart while playing), and with AU_NAME
//   before_unit.png, unit.png (the face before and after that slider is set to 1), and OUT_DIR/report.json.
const path = require('path');
const { withViewerPage } = require('./viewer_page');

(async () => {
  const [url, out, unit] = process.argv.slice(2);
  await withViewerPage(url, out, { width: 1400, height: 1300 }, async (page, report) => {
    const face = page.locator('#face');
    await page.waitForTimeout(500);
    report.time_a = await page.evaluate(() => window.viewer.time);
    await face.screenshot({ path: path.join(out, 'playing_a.png') });
    await page.waitForTimeout(1500);
    report.time_b = await page.evaluate(() => window.viewer.time);
    await face.screenshot({ path: path.join(out, 'playing_b.png') });
    report.duration = await page.evaluate(() => window.viewer.duration);
    report.has_video = await page.evaluate(() => !document.getElementById('source-box').hidden);
    report.has_curves = await page.evaluate(() => !document.getElementById('curves-box').hidden);
    if (report.has_video) {
      await page.evaluate(() => window.viewer.seek(window.viewer.duration * 0.5));
      await page.waitForFunction(() => !document.getElementById('source').seeking, null, { timeout: 20000 });
      report.video = await page.evaluate(() => {
        const v = document.getElementById('source');
        return { time: v.currentTime, face_time: window.viewer.time, ready: v.readyState, error: !!v.error };
      });
    }
    report.editor = await page.evaluate(() => !document.getElementById('editor').hidden);
    if (unit) {
      await face.screenshot({ path: path.join(out, 'before_unit.png') });
      await page.evaluate(([name]) => window.viewer.setUnit(name, 1.0), [unit]);
      await page.waitForTimeout(200);
      await face.screenshot({ path: path.join(out, 'unit.png') });
      report.recipe = await page.evaluate(() => window.viewer.recipe());
      report.fap = await page.evaluate(() => window.viewer.fap());
    }
    report.page_errors = await page.evaluate(() => window.viewer.errors);
    await page.screenshot({ path: path.join(out, 'page.png'), fullPage: true });
  });
})().catch((e) => { console.error(String(e)); process.exit(1); });
