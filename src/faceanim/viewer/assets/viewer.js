// faceanim viewer: the animated face (three.js), its source video in step, FAP curves with a cursor,
// and, for a model with action-unit morph targets, sliders that mix an expression by hand.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const AU_NAME = /^AU(\d+)([LR]?)$/i;
const MAX_CURVES = 12;
const SYNC_TOLERANCE = 0.12; // seconds the video may drift from the face before it is re-seated

// The page's state, open to scripts (the browser tests drive it through these).
const viewer = { ready: false, time: 0, duration: 0, playing: true, speed: 1, editing: false, errors: [] };
window.viewer = viewer;
window.addEventListener('error', (event) => fail(event.message));
window.addEventListener('unhandledrejection', (event) => fail(String(event.reason)));

function fail(message) {
  viewer.errors.push(message);
  $('status').textContent = `error: ${message}`;
  console.error(message);
}

async function main() {
  const config = await (await fetch('/config.json')).json();
  $('title').textContent = config.title;
  const canvas = $('face');
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(canvas.width, canvas.height, false);
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x707070, 2.2));
  const key = new THREE.DirectionalLight(0xffffff, 1.6);
  key.position.set(0.4, 0.8, 2.0);
  scene.add(key);

  const gltf = await new GLTFLoader().loadAsync(config.model);
  scene.add(gltf.scene);
  const camera = frame(gltf.scene);
  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(new THREE.Box3().setFromObject(gltf.scene).getCenter(new THREE.Vector3()));
  controls.update();

  const mixer = new THREE.AnimationMixer(gltf.scene);
  const clip = gltf.animations[0];
  if (clip) {
    mixer.clipAction(clip).play();
    viewer.duration = clip.duration;
  }
  let face = null;
  gltf.scene.traverse((o) => { if (!face && o.isMesh && o.morphTargetDictionary) face = o; });

  const video = config.video ? setUpVideo(config.video) : null;
  const curves = config.curves ? await setUpCurves(config.curves) : null;
  if (face) setUpEditor(face);

  const scrub = $('scrub');
  scrub.addEventListener('input', () => seek((scrub.value / 1000) * viewer.duration));
  $('play').addEventListener('click', () => (viewer.playing ? pause() : play()));
  $('speed').addEventListener('change', (e) => { viewer.speed = Number(e.target.value); });

  function apply() {
    if (!viewer.editing && clip) mixer.setTime(viewer.duration ? viewer.time % viewer.duration : 0);
    if (video && video.readyState >= 1) {
      video.playbackRate = viewer.speed;
      if (viewer.playing && !viewer.editing) {
        if (video.paused) video.play().catch(() => {});
      } else if (!video.paused) video.pause();
      const drift = Math.abs(video.currentTime - viewer.time);
      if (drift > (viewer.playing ? SYNC_TOLERANCE : 0.02)) video.currentTime = viewer.time;
    }
    scrub.value = viewer.duration ? Math.round((1000 * viewer.time) / viewer.duration) : 0;
    $('time').textContent = `${viewer.time.toFixed(2)} s / ${viewer.duration.toFixed(2)} s`;
    if (curves) curves.draw(viewer.time);
    renderer.render(scene, camera);
  }

  let last = performance.now();
  function tick(now) {
    const dt = Math.min(0.1, (now - last) / 1000);
    last = now;
    if (viewer.playing && !viewer.editing && viewer.duration > 0) {
      viewer.time = (viewer.time + dt * viewer.speed) % viewer.duration;
    }
    apply();
    requestAnimationFrame(tick);
  }

  function seek(t) {
    pause();
    viewer.editing = false;
    viewer.time = Math.max(0, Math.min(t, viewer.duration));
    apply();
  }
  function pause() { viewer.playing = false; $('play').textContent = 'Play'; }
  function play() { viewer.editing = false; viewer.playing = true; $('play').textContent = 'Pause'; }
  Object.assign(viewer, { seek, play, pause, render: apply });

  function setUpVideo(url) {
    $('source-box').hidden = false;
    const element = $('source');
    element.src = url;
    element.addEventListener('loadedmetadata', () => {
      if (!viewer.duration) viewer.duration = element.duration;
    });
    element.addEventListener('error', () => fail(`the source video ${url} cannot be played by this browser`));
    return element;
  }

  function setUpEditor(mesh) {
    const units = Object.entries(mesh.morphTargetDictionary).filter(([name]) => AU_NAME.test(name));
    if (!units.length) return;
    $('editor').hidden = false;
    const table = (mesh.userData.faceanim || {}).au_faps || null;
    const weights = {};
    const sliders = $('sliders');
    for (const [name, index] of units.sort((a, b) => auNumber(a[0]) - auNumber(b[0]))) {
      const label = document.createElement('label');
      label.innerHTML = `<span>${name}</span><input type="range" min="0" max="2" step="0.01" value="0"
        data-unit="${name}"><output>0.00</output>`;
      const input = label.querySelector('input');
      input.addEventListener('input', () => {
        if (!viewer.editing) { // leave the animation: every morph starts from rest
          pause();
          viewer.editing = true;
          mesh.morphTargetInfluences.fill(0);
        }
        weights[name] = Number(input.value);
        mesh.morphTargetInfluences[index] = weights[name];
        label.querySelector('output').textContent = weights[name].toFixed(2);
        $('recipe').textContent = recipe(weights);
        apply();
      });
      sliders.appendChild(label);
    }
    $('save-recipe').addEventListener('click', () => download('expression.au.txt', `${recipe(weights)}\n`));
    const fapButton = $('save-fap');
    if (!table) {
      fapButton.disabled = true;
      fapButton.title = 'this model carries no AU-to-FAP table';
    }
    fapButton.addEventListener('click', () => download('expression.fap', fapFile(weights, table)));
    viewer.setUnit = (name, value) => {
      const input = sliders.querySelector(`input[data-unit="${name}"]`);
      input.value = value;
      input.dispatchEvent(new Event('input'));
    };
    viewer.recipe = () => recipe(weights);
    viewer.fap = () => fapFile(weights, table);
  }

  async function setUpCurves(url) {
    let data = await (await fetch(url)).json();
    $('curves-box').hidden = false;
    $('curves-title').textContent = data.title;
    const canvas = $('curves');
    const context = canvas.getContext('2d');
    const background = document.createElement('canvas');
    background.width = canvas.width;
    background.height = canvas.height;
    const g = background.getContext('2d');
    // The most active curves only, so the plot stays readable (the title says how many are shown).
    const ranked = data.values.map((c, i) => [Math.max(0, ...c.map(Math.abs)), i]).sort((a, b) => b[0] - a[0]);
    const shown = ranked.slice(0, MAX_CURVES).map(([, i]) => i).sort((a, b) => a - b);
    data = { ...data, names: shown.map((i) => data.names[i]), values: shown.map((i) => data.values[i]),
      title: `${data.title || 'curves'}${shown.length < ranked.length ? `: the ${shown.length} most active of ${ranked.length}` : ''}` };
    const frames = data.values.length ? data.values[0].length : 0;
    const span = Math.max(1e-9, ...data.values.flat().map(Math.abs));
    const duration = frames / data.fps;
    const x = (t) => (t / Math.max(duration, viewer.duration, 1e-9)) * canvas.width;
    const y = (v) => canvas.height / 2 - (v / span) * (canvas.height / 2 - 14);
    g.fillStyle = '#fff';
    g.fillRect(0, 0, canvas.width, canvas.height);
    g.strokeStyle = '#ddd';
    g.beginPath(); g.moveTo(0, y(0)); g.lineTo(canvas.width, y(0)); g.stroke();
    data.values.forEach((curve, i) => {
      g.strokeStyle = `hsl(${(i * 137.5) % 360} 65% 42%)`;
      g.beginPath();
      curve.forEach((v, f) => (f ? g.lineTo(x(f / data.fps), y(v)) : g.moveTo(x(0), y(v))));
      g.stroke();
      g.fillStyle = g.strokeStyle;
      g.fillText(data.names[i], 6 + (i % 6) * 200, 12 + Math.floor(i / 6) * 12);
    });
    return {
      draw(t) {
        context.drawImage(background, 0, 0);
        context.strokeStyle = '#d22';
        context.beginPath(); context.moveTo(x(t), 0); context.lineTo(x(t), canvas.height); context.stroke();
      },
    };
  }

  apply();
  requestAnimationFrame(tick);
  viewer.ready = true;
  $('status').textContent = clip ? `${clip.duration.toFixed(2)} s animation` : 'still model';
}

function frame(object) {
  const box = new THREE.Box3().setFromObject(object);
  const centre = box.getCenter(new THREE.Vector3());
  const radius = 0.5 * box.getSize(new THREE.Vector3()).length() || 1;
  const camera = new THREE.PerspectiveCamera(25, 1, radius / 100, radius * 100);
  camera.position.copy(centre).add(new THREE.Vector3(0, 0, radius / Math.sin(THREE.MathUtils.degToRad(12.5))));
  camera.lookAt(centre);
  return camera;
}

function auNumber(name) { return Number(AU_NAME.exec(name)[1]); }

// The recipe as `faceanim express --au` reads it: "6:0.80,12:1.00" (units at 0 left out).
function recipe(weights) {
  return Object.entries(weights)
    .filter(([, w]) => w > 0)
    .sort((a, b) => auNumber(a[0]) - auNumber(b[0]))
    .map(([name, w]) => `${name.replace(/^AU/i, '')}:${w.toFixed(2)}`)
    .join(',');
}

// One frame of MPEG-4 FAPs (the .fap 2.1 text format) mixed from each unit's FAPs at full intensity.
function fapFile(weights, table) {
  const values = new Array(68).fill(0);
  const mask = new Array(68).fill(0);
  for (const [name, w] of Object.entries(weights)) {
    for (const [fap, value] of Object.entries((table || {})[name] || {})) {
      values[Number(fap) - 1] += w * value;
      mask[Number(fap) - 1] = 1;
    }
  }
  const present = values.map((v, i) => [v, i]).filter(([, i]) => mask[i]);
  return `2.1 expression 25 1\n${mask.join(' ')}\n0 ${present.map(([v]) => Math.round(v)).join(' ')}\n`;
}

function download(name, text) {
  const link = document.createElement('a');
  link.href = URL.createObjectURL(new Blob([text], { type: 'text/plain' }));
  link.download = name;
  link.click();
  URL.revokeObjectURL(link.href);
}

main().catch((error) => fail(error && error.message ? error.message : String(error)));
