// The viewer page opened in headless Chromium (Debian's, through playwright-core in tools/node), as the
// browser tests drive it: WebGL through SwiftShader (no GPU), console and page errors collected, and the
// page's own viewer ready. Used by browser_check.js and browser_layout.js.
const path = require('path');
const fs = require('fs');
const { chromium } = require(path.join(__dirname, 'node', 'node_modules', 'playwright-core'));

// Open `url` in a window of `viewport` ({width, height}), wait for the viewer, run `look(page, report)`,
// and write `report` (with the errors seen) to OUT_DIR/report.json however it ends.
async function withViewerPage(url, out, viewport, look) {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
      '--autoplay-policy=no-user-gesture-required'],
  });
  const report = { console_errors: [] };
  try {
    const page = await browser.newPage({ viewport });
    page.on('console', (m) => { if (m.type() === 'error') report.console_errors.push(m.text()); });
    page.on('pageerror', (e) => report.console_errors.push(String(e)));
    await page.goto(url);
    await page.waitForFunction(() => window.viewer && (window.viewer.ready || window.viewer.errors.length),
      null, { timeout: 90000 });
    await look(page, report);
  } finally {
    fs.writeFileSync(path.join(out, 'report.json'), JSON.stringify(report));
    await browser.close();
  }
}

module.exports = { withViewerPage };
