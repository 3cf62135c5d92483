// faceanim viewer: the animated face (three.js), its source video in step, FAP curves with a cursor
// (one chart per group of the face, each on its own scale), and, for a model with action-unit morph
// targets, sliders that start from the model's AU recipe and adjust it.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const AU_NAME = /^AU(\d+)([LR]?)$/i;
const SVG = 'http://www.w3.org/2000/svg';
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
  const editor = face ? setUpEditor(face) : null;
  // Play controls only where something plays: an animation or a video.
  $('transport').hidden = !clip && !video;
  $('face-caption').textContent = clip ? 'animated face (drag to turn)' : 'still face (drag to turn)';
  if (!clip && !video) viewer.playing = false;

  const scrub = $('scrub');
  scrub.addEventListener('input', () => seek((scrub.value / 1000) * viewer.duration));
  $('play').addEventListener('click', () => (viewer.playing ? pause() : play()));
  $('speed').addEventListener('change', (e) => { viewer.speed = Number(e.target.value); });

  function apply() {
    if (!viewer.editing && clip) mixer.setTime(viewer.duration ? viewer.time % viewer.duration : 0);
    if (editor) editor.adjust(); // the sliders' adjustment, at the clip's time
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

  // The sliders start from the model's recipe (a `faceanim express` .glb carries it in its extras) and
  // adjust the expression's apex, the recipe at full strength. The made expression is not the plain sum
  // of its units' morphs (the muscles interact), so the apex is mixed as
  //   a * expression + sum over units of (slider - a * recipe) * unit,
  // where a, the share of the recipe still in place (each recipe unit's slider over its recipe value, at
  // most 1, averaged), is 1 at the recipe, so the face is exactly the one made, and 0 with every recipe
  // unit at 0, so the face is the units alone (the rest face with all at 0). A still carries the
  // expression as the morph target "expression". An animated one (onset, apex, offset) carries it as its
  // clip: the clip's shapes are scaled by a and the units' part by e(t), the clip's strength at time t
  // (its shape at t projected on its shape at the apex, the frame that moves the face most: 0 at rest,
  // 1 at the apex), so the animation plays the adjusted expression over time. A model without a recipe
  // starts every slider at 0 and adds the units alone.
  function setUpEditor(mesh) {
    const units = Object.entries(mesh.morphTargetDictionary).filter(([name]) => AU_NAME.test(name));
    if (!units.length) return null;
    $('editor').hidden = false;
    const extras = mesh.userData.faceanim || {};
    const table = extras.au_faps || null;
    const start = parseRecipe(extras.recipe || '');
    const weights = { ...start }; // every unit of the recipe, with a slider or not
    if (Object.keys(start).length) {
      $('editor-help').textContent = `(they start from the model's recipe ${recipe(start)} and adjust `
        + `${clip ? 'its apex; the animation plays it' : 'it'})`;
      $('recipe').textContent = recipe(weights);
    }
    const expression = mesh.morphTargetDictionary.expression;
    const inRecipe = Object.keys(start).filter((k) => start[k] > 0);
    const strength = clip && expression === undefined && inRecipe.length ? clipStrength(mesh, clip, units) : null;
    let share = 1;
    function mix() {
      share = inRecipe.length ? inRecipe.reduce((sum, k) => sum + Math.min(1, (weights[k] || 0) / start[k]), 0)
        / inRecipe.length : 1;
      adjust();
    }
    // The face at the clip's time (the mixer has just set the clip's weights) or the still's, adjusted.
    function adjust() {
      const influences = mesh.morphTargetInfluences;
      let e = 1;
      if (strength) {
        e = strength.at(influences);
        for (const index of strength.shapes) influences[index] *= share;
      } else if (expression !== undefined && inRecipe.length) influences[expression] = share;
      for (const [name, index] of units) influences[index] = e * ((weights[name] || 0) - share * (start[name] || 0));
    }
    const sliders = $('sliders');
    for (const [name] of [...units].sort((a, b) => auNumber(a[0]) - auNumber(b[0]))) {
      const value = start[name] || 0;
      const label = document.createElement('label');
      label.classList.toggle('in-recipe', name in start);
      label.innerHTML = `<span>${name}</span><input type="range" min="0" max="2" step="0.01" value="${value}"
        data-unit="${name}"><output>${value.toFixed(2)}</output>`;
      const input = label.querySelector('input');
      input.addEventListener('input', () => {
        if (strength) { // pause; from playing, show the apex being adjusted (a time scrubbed to stays)
          if (viewer.playing) viewer.time = strength.apex;
          pause();
        } else if (!viewer.editing) { // leave the animation, keeping the expression shown; the units adjust it
          pause();
          viewer.editing = true;
        }
        weights[name] = Number(input.value);
        mix();
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
    viewer.units = () => Object.fromEntries([...sliders.querySelectorAll('input')].map(
      (i) => [i.dataset.unit, Number(i.value)]));
    viewer.influences = () => Object.fromEntries(Object.entries(mesh.morphTargetDictionary).map(
      ([name, index]) => [name, mesh.morphTargetInfluences[index]]));
    viewer.recipe = () => recipe(weights);
    viewer.fap = () => fapFile(weights, table);
    viewer.apex = strength ? strength.apex : null;
    viewer.strength = () => (strength ? strength.last : null);
    return { adjust };
  }

  // An animated expression's strength over time: its clip's shapes (the morph targets other than the
  // units) at a time, w, projected on those at the apex, wA, through the shapes' inner products G:
  // e = w.G.wA / wA.G.wA, clipped to [0, 1]. The apex is the clip's key whose shape is largest.
  function clipStrength(mesh, clip, units) {
    const count = mesh.morphTargetInfluences.length;
    const unitIndex = new Set(units.map(([, index]) => index));
    const shapes = [...Array(count).keys()].filter((i) => !unitIndex.has(i));
    const track = clip.tracks.find((t) => t.name.endsWith('.morphTargetInfluences'));
    const targets = mesh.geometry.morphAttributes.position || [];
    if (!track || !shapes.length || targets.length !== count) return null;
    // G over the shapes, from their positions (relative, as glTF's are); a stride keeps it light on big meshes.
    const size = targets[0].count;
    const stride = Math.max(1, Math.floor((shapes.length * shapes.length * size) / 2e7));
    const G = shapes.map(() => new Float64Array(shapes.length));
    for (let a = 0; a < shapes.length; a++) {
      for (let b = a; b < shapes.length; b++) {
        const [p, q] = [targets[shapes[a]], targets[shapes[b]]];
        let sum = 0;
        for (let v = 0; v < size; v += stride) sum += p.getX(v) * q.getX(v) + p.getY(v) * q.getY(v) + p.getZ(v) * q.getZ(v);
        G[a][b] = G[b][a] = sum;
      }
    }
    const dot = (w, u) => {
      let sum = 0;
      for (let a = 0; a < shapes.length; a++) for (let b = 0; b < shapes.length; b++) sum += w[a] * G[a][b] * u[b];
      return sum;
    };
    const width = track.values.length / track.times.length; // the values of one key
    const keys = Array.from(track.times, (t, k) => shapes.map((i) => track.values[k * width + i]));
    let apexKey = 0;
    keys.forEach((w, k) => { if (dot(w, w) > dot(keys[apexKey], keys[apexKey])) apexKey = k; });
    const wA = keys[apexKey];
    const norm = dot(wA, wA);
    if (!(norm > 0)) return null;
    const result = {
      apex: track.times[apexKey], shapes, last: null,
      at(influences) {
        result.last = Math.min(1, Math.max(0, dot(shapes.map((i) => influences[i]), wA) / norm));
        return result.last;
      },
    };
    return result;
  }

  // One chart per group of FAPs (jaw, lips, ...; grouped and ranked by faceanim.viewer.fap_curves), each
  // on its own y scale with ticks and its unit, over a shared time axis, and a cursor at the face's time.
  async function setUpCurves(url) {
    const data = await (await fetch(url)).json();
    $('curves-box').hidden = false;
    $('curves-title').textContent = data.title;
    const end = Math.max(data.times.length ? data.times[data.times.length - 1] : 0, viewer.duration, 1e-9);
    const charts = data.groups.map((group) => chart(group, data.times, end));
    return {
      draw(t) { for (const c of charts) c.cursor(t); },
    };
  }

  function chart(group, times, end) {
    const [W, H] = [600, 150];
    const pad = { left: 52, right: 10, top: 8, bottom: 22 };
    const box = document.createElement('figure');
    box.className = 'chart';
    box.dataset.group = group.name;
    box.innerHTML = `<figcaption><b></b><span class="unit"></span><span class="note"></span></figcaption>`;
    box.querySelector('b').textContent = group.name;
    box.querySelector('.unit').textContent = group.unit;
    box.querySelector('.note').textContent = group.note;
    const svg = element('svg', { viewBox: `0 0 ${W} ${H}`, role: 'img', 'aria-label': `${group.name} curves` });
    box.appendChild(svg);
    const values = group.curves.flatMap((c) => c.values).filter((v) => v !== null);
    let [lo, hi] = [Math.min(0, ...values), Math.max(0, ...values)];
    if (hi - lo < 1e-9) [lo, hi] = [lo - 1, hi + 1];
    const yTicks = niceTicks(lo, hi, 4);
    [lo, hi] = [Math.min(lo, yTicks[0]), Math.max(hi, yTicks[yTicks.length - 1])];
    const x = (t) => pad.left + (t / end) * (W - pad.left - pad.right);
    const y = (v) => H - pad.bottom - ((v - lo) / (hi - lo)) * (H - pad.top - pad.bottom);
    for (const v of yTicks) {
      svg.appendChild(element('line', { class: 'grid', x1: pad.left, x2: W - pad.right, y1: y(v), y2: y(v) }));
      const label = element('text', { class: 'tick y', x: pad.left - 4, y: y(v) + 4, 'text-anchor': 'end' });
      label.textContent = tickText(v, yTicks);
      svg.appendChild(label);
    }
    const xTicks = niceTicks(0, end, 6).filter((t) => t <= end + 1e-9);
    for (const t of xTicks) {
      svg.appendChild(element('line', { class: 'axis', x1: x(t), x2: x(t), y1: H - pad.bottom, y2: H - pad.bottom + 4 }));
      const label = element('text', { class: 'tick x', x: x(t), y: H - 6, 'text-anchor': 'middle' });
      label.textContent = `${tickText(t, xTicks)} s`;
      svg.appendChild(label);
    }
    svg.appendChild(element('line', { class: 'axis', x1: pad.left, x2: W - pad.right, y1: H - pad.bottom, y2: H - pad.bottom }));
    const legend = document.createElement('div');
    legend.className = 'legend';
    // The unnamed curves first, thin and grey, so the named ones are drawn over them.
    const order = [...group.curves.filter((c) => !c.named), ...group.curves.filter((c) => c.named)];
    order.forEach((curve) => {
      const colour = curve.named ? `hsl(${(group.curves.indexOf(curve) * 137.5 + 210) % 360} 65% 40%)` : '#c4c4c4';
      let d = '';
      curve.values.forEach((v, f) => {
        if (v === null) return;
        d += `${d && curve.values[f - 1] !== null ? 'L' : 'M'}${x(times[f]).toFixed(1)},${y(v).toFixed(1)}`;
      });
      svg.appendChild(element('path', { d, fill: 'none', stroke: colour, 'stroke-width': curve.named ? 1.5 : 0.8 }));
      if (curve.named) {
        const item = document.createElement('span');
        item.style.color = colour;
        item.textContent = curve.label;
        legend.appendChild(item);
      }
    });
    const cursor = element('line', { class: 'cursor', y1: pad.top, y2: H - pad.bottom, x1: x(0), x2: x(0) });
    svg.appendChild(cursor);
    box.appendChild(legend);
    $('charts').appendChild(box);
    let shown = null;
    return {
      cursor(t) {
        const at = x(Math.min(t, end)).toFixed(1);
        if (at !== shown) { cursor.setAttribute('x1', at); cursor.setAttribute('x2', at); shown = at; }
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

// A recipe as faceanim writes it ("6:0.80,12:1.00") as {AU6: 0.8, AU12: 1.0}; a code repeated adds up.
function parseRecipe(text) {
  const weights = {};
  for (const part of String(text).split(',')) {
    const [code, value] = part.split(':').map((s) => s.trim());
    const name = `AU${code.replace(/^AU/i, '').replace(/^0+(?=\d)/, '')}`;
    if (code && AU_NAME.test(name) && Number.isFinite(Number(value))) weights[name] = (weights[name] || 0) + Number(value);
  }
  return weights;
}

function element(tag, attributes) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attributes)) node.setAttribute(k, v);
  return node;
}

// About `count` round values (1, 2 or 5 times a power of ten apart) spanning lo..hi.
function niceTicks(lo, hi, count) {
  const raw = (hi - lo) / Math.max(1, count);
  const power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw);
  const ticks = [];
  for (let v = Math.floor(lo / step) * step; v <= hi + step * 0.5; v += step) {
    ticks.push(Math.abs(v) < step * 1e-6 ? 0 : v);
    if (v >= hi) break;
  }
  return ticks;
}

function tickText(v, ticks) {
  const step = ticks.length > 1 ? Math.abs(ticks[1] - ticks[0]) : 1;
  return v.toFixed(Math.max(0, Math.min(4, -Math.floor(Math.log10(step) + 1e-9))));
}

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
