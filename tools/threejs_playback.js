// Play a glTF's animation in three.js (the viewer's own copy, src/faceanim/viewer/assets/three) inside
// headless Chromium (Debian's, through playwright-core in tools/node) and report what three.js shows,
// for tests/test_playback.py.
// Usage: node tools/threejs_playback.js FILE.glb TIMES.json OUT.json
//   For each time t (seconds) an AnimationMixer playing the file's first clip is set to t
//   (mixer.setTime), and every vertex is read with mesh.getVertexPosition (which applies the morph
//   targets on the CPU), in world space and glTF's axes. OUT.json: {duration, targetNames, vertices,
//   influences: [per time, per target], positions: [per time, flat x y z ...], errors}.
const path = require('path');
const fs = require('fs');
const http = require('http');
const { chromium } = require(path.join(__dirname, 'node', 'node_modules', 'playwright-core'));

const THREE_DIR = path.join(__dirname, '..', 'src', 'faceanim', 'viewer', 'assets', 'three');
const PAGE = `<!doctype html><meta charset="utf-8"><title>playback</title>
<script type="importmap">{"imports": {"three": "/three/three.module.min.js", "three/addons/": "/three/addons/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
window.playback = async (times) => {
  const gltf = await new GLTFLoader().loadAsync('/model.glb');
  let mesh = null;
  gltf.scene.traverse((o) => { if (!mesh && o.isMesh) mesh = o; });
  const clip = gltf.animations[0];
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1); // so the clip's last key can be asked for (a loop wraps to 0 there)
  action.clampWhenFinished = true;
  action.play();
  const count = mesh.geometry.attributes.position.count;
  const v = new THREE.Vector3();
  const out = { duration: clip.duration, vertices: count, influences: [], positions: [],
    targetNames: Object.keys(mesh.morphTargetDictionary || {}) };
  for (const t of times) {
    mixer.setTime(t);
    gltf.scene.updateMatrixWorld(true);
    const flat = new Array(3 * count);
    for (let i = 0; i < count; i++) {
      mesh.getVertexPosition(i, v).applyMatrix4(mesh.matrixWorld);
      flat[3 * i] = v.x; flat[3 * i + 1] = v.y; flat[3 * i + 2] = v.z;
    }
    out.positions.push(flat);
    out.influences.push(Array.from(mesh.morphTargetInfluences));
  }
  return out;
};
window.ready = true;
</script>`;

function serve(glb) {
  const types = { '.js': 'text/javascript', '.glb': 'model/gltf-binary', '.html': 'text/html' };
  const server = http.createServer((request, response) => {
    const url = decodeURIComponent(new URL(request.url, 'http://127.0.0.1').pathname);
    let file = null;
    if (url === '/') {
      response.writeHead(200, { 'Content-Type': types['.html'] });
      response.end(PAGE);
      return;
    }
    if (url === '/favicon.ico') {
      response.writeHead(204);
      response.end();
      return;
    }
    if (url === '/model.glb') file = glb;
    else if (url.startsWith('/three/')) {
      const inside = path.resolve(THREE_DIR, '.' + url.slice('/three'.length));
      if (inside.startsWith(THREE_DIR + path.sep)) file = inside;
    }
    if (!file || !fs.existsSync(file) || !fs.statSync(file).isFile()) {
      response.writeHead(404);
      response.end();
      return;
    }
    response.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    fs.createReadStream(file).pipe(response);
  });
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () => resolve(server)));
}

(async () => {
  const [glb, timesFile, out] = process.argv.slice(2);
  const times = JSON.parse(fs.readFileSync(timesFile, 'utf8'));
  const server = await serve(path.resolve(glb));
  const browser = await chromium.launch({ executablePath: process.env.CHROMIUM || '/usr/bin/chromium' });
  const errors = [];
  try {
    const page = await browser.newPage();
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    page.on('pageerror', (e) => errors.push(String(e)));
    await page.goto(`http://127.0.0.1:${server.address().port}/`);
    await page.waitForFunction(() => window.ready === true, null, { timeout: 60000 });
    const result = await page.evaluate((t) => window.playback(t), times);
    result.errors = errors;
    fs.writeFileSync(out, JSON.stringify(result));
  } finally {
    await browser.close();
    server.close();
  }
})().catch((e) => { console.error(String(e)); process.exit(1); });
