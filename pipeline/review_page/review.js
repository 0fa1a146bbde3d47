// The review page of hmc (docs/review.md): one frame cursor syncing both
// cameras' footage with the tracked dots, the solved mesh in 3D, the run's
// plots and warnings; fixing the tracks (kept in localStorage, exported as
// track_fixes.csv, docs/formats.md). Every data file is a script that calls
// hmcReview.meta / .topology / .chunk (JSONP-like), so the page needs no
// fetch and works from file://. Footage proxies are JPEGs loaded by <img>.
'use strict';

const hmcReview = (function () {
  const STATE_NAMES = ['named', 'flagged', 'interpolated', 'rejected'];
  const STATE_COLOURS = ['#3ddc5a', '#ffa028', '#3cc8ff', '#ff3c3c'];
  const FIXED_COLOUR = '#ff4cff';
  const S = {
    meta: null, topology: null, chunks: new Map(), loading: new Map(), inflating: new Map(),
    index: 0, playing: false, timer: null, images: [], cams: [],
    fixes: [], selected: null, drag: null, three: null, errors: [],
    firstRender: null, testMode: /[?&]test=(1|open)/.test(location.search),
  };

  // ---------- loading ----------
  function loadScript(src) {
    return new Promise((resolve, reject) => {
      const s = document.createElement('script');
      s.src = src;
      s.onload = () => resolve();
      s.onerror = () => { S.errors.push('cannot load ' + src); reject(new Error('cannot load ' + src)); };
      document.head.appendChild(s);
    });
  }
  function decodeBase64(text) {
    const bin = atob(text);
    const out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; ++i) out[i] = bin.charCodeAt(i);
    return out.buffer;
  }
  function chunkOf(index) { return Math.floor(index / S.meta.chunk_frames); }
  function loadChunk(k) {
    if (k < 0 || k >= S.meta.chunks) return Promise.resolve();
    if (S.chunks.has(k)) return Promise.resolve();
    if (!S.loading.has(k)) {
      // The script calls chunk(), which inflates the meshes: done when both are.
      S.loading.set(k, loadScript('data/chunk_' + String(k).padStart(5, '0') + '.js')
        .then(() => S.inflating.get(k)).finally(() => S.inflating.delete(k)));
    }
    return S.loading.get(k);
  }
  // Keeps the chunks near the cursor, drops the far ones (a long take's
  // mesh is not held whole).
  function trimChunks(k) {
    for (const key of Array.from(S.chunks.keys())) {
      if (Math.abs(key - k) > 3) { S.chunks.delete(key); S.loading.delete(key); }
    }
  }

  // ---------- frames ----------
  const frameOf = (i) => S.meta.first_frame + i;
  const indexOf = (f) => f - S.meta.first_frame;
  function frameData(i) {
    const c = S.chunks.get(chunkOf(i));
    return c ? c.frames[i - chunkOf(i) * S.meta.chunk_frames] : null;
  }

  // ---------- fixes (localStorage) ----------
  const storageKey = () => 'hmc_review_fixes:' + S.meta.work;
  function loadFixes() {
    try { S.fixes = JSON.parse(localStorage.getItem(storageKey()) || '[]'); } catch (e) { S.fixes = []; }
  }
  function saveFixes() {
    try { localStorage.setItem(storageKey(), JSON.stringify(S.fixes)); } catch (e) { /* file:// may refuse */ }
    renderFixTable();
  }
  function addFix(fix) {
    S.fixes.push(fix);
    S.fixes.sort((a, b) => a.frame - b.frame || a.camera.localeCompare(b.camera));
    saveFixes();
    draw();
  }
  function csvNumber(v) { return v === null || v === undefined ? '' : (+v).toFixed(3); }
  function fixesCsv() {
    let text = 'frame,camera,marker,action,x,y,to\n';
    for (const f of S.fixes) {
      text += [f.frame, f.camera, f.marker || '', f.action, csvNumber(f.x), csvNumber(f.y), f.to || ''].join(',') + '\n';
    }
    return text;
  }
  // The dots of one camera at frame index i, with the page's fixes applied
  // (what the fixed run would start from at that frame).
  function dotsAt(i, camera) {
    const fd = frameData(i);
    if (!fd) return [];
    const raw = fd.tracks[camera] || [];
    const names = S.meta.markers;
    const camName = S.meta.cameras[camera].name;
    const frame = frameOf(i);
    let dots = [];
    for (let j = 0; j < raw.length; j += 4) {
      dots.push({ marker: names[raw[j]], x: raw[j + 1], y: raw[j + 2], state: raw[j + 3], fixed: false });
    }
    // absent: the marker from its frame on; unnamed: the dot from its
    // frame on, which the tracker follows -- previewed as the dot that
    // marker holds in the run's tracks (docs/review.md).
    const absent = new Set(), unnamed = new Set();
    for (const f of S.fixes) {
      if (f.camera !== camName || f.frame > frame) continue;
      if (f.action === 'absent') absent.add(f.marker);
      if (f.action === 'rename') { absent.delete(f.to); unnamed.delete(f.to); }
      if (f.action === 'move') { absent.delete(f.marker); unnamed.delete(f.marker); }
      if (f.action === 'unname' && f.marker && f.frame < frame) unnamed.add(f.marker);
      if (f.frame !== frame) continue;
      const d = dots.find((o) => o.marker === f.marker && (f.x === null || Math.hypot(o.x - f.x, o.y - f.y) < 1e-2)) ||
                dots.find((o) => f.x !== null && Math.hypot(o.x - f.x, o.y - f.y) < 1e-2);
      if (f.action === 'rename') {
        dots = dots.filter((o) => o.marker !== f.to || o === d);
        if (d) { d.marker = f.to; d.fixed = true; }
        else dots.push({ marker: f.to, x: f.x, y: f.y, state: 0, fixed: true });
      } else if (f.action === 'unname' && d) {
        dots = dots.filter((o) => o !== d);
      } else if (f.action === 'move') {
        const m = dots.find((o) => o.marker === f.marker);
        if (m) { m.x = f.x; m.y = f.y; m.fixed = true; }
        else dots.push({ marker: f.marker, x: f.x, y: f.y, state: 0, fixed: true });
      }
    }
    return dots.filter((o) => !absent.has(o.marker) && !(unnamed.has(o.marker) && !o.fixed));
  }

  // ---------- cameras ----------
  function buildCameras() {
    const box = document.getElementById('cameras');
    S.meta.cameras.forEach((cam, c) => {
      const div = document.createElement('div');
      div.className = 'camera';
      const canvas = document.createElement('canvas');
      const label = document.createElement('div');
      label.className = 'label';
      label.textContent = cam.name;
      div.appendChild(canvas);
      div.appendChild(label);
      box.appendChild(div);
      const view = { canvas, ctx: canvas.getContext('2d'), c, shownFrame: null, fit: null };
      S.cams.push(view);
      canvas.addEventListener('mousemove', (e) => onMouseMove(view, e));
      canvas.addEventListener('mousedown', (e) => onMouseDown(view, e));
      canvas.addEventListener('mouseup', (e) => onMouseUp(view, e));
      canvas.addEventListener('mouseleave', () => { hideTooltip(); S.drag = null; });
    });
  }
  function proxyUrl(c, frame) {
    return 'footage/' + S.meta.cameras[c].name + '/' + String(frame).padStart(6, '0') + '.jpg';
  }
  // Proxy images near the cursor, loaded ahead; far ones dropped.
  function image(c, i) {
    const key = c + ':' + i;
    let img = S.images[key];
    if (!img) {
      if (!S.meta.footage_frames || !S.meta.footage_frames[c].has(frameOf(i))) return null;
      img = new Image();
      img.onload = () => { if (i === S.index) draw(); };
      img.onerror = () => { img.failed = true; S.errors.push('cannot load ' + img.src); };
      img.src = proxyUrl(c, frameOf(i));
      S.images[key] = img;
    }
    return img;
  }
  function prefetch(i) {
    for (let d = 1; d <= 6; ++d) {
      for (let c = 0; c < S.meta.cameras.length; ++c) {
        if (i + d < S.meta.num_frames) image(c, i + d);
      }
    }
    for (const key of Object.keys(S.images)) {
      const j = +key.split(':')[1];
      if (j < i - 12 || j > i + 12) delete S.images[key];
    }
  }
  // Full-image px -> canvas px and back, through the proxy's crop and scale.
  function fitOf(view) {
    const cam = S.meta.cameras[view.c];
    const w = view.canvas.clientWidth, h = view.canvas.clientHeight;
    if (view.canvas.width !== w || view.canvas.height !== h) { view.canvas.width = w; view.canvas.height = h; }
    const s = Math.min(w / cam.crop[2], h / cam.crop[3]);
    return { s, ox: (w - cam.crop[2] * s) / 2 - cam.crop[0] * s, oy: (h - cam.crop[3] * s) / 2 - cam.crop[1] * s };
  }
  const toCanvas = (fit, x, y) => [(x + 0.5) * fit.s + fit.ox, (y + 0.5) * fit.s + fit.oy];
  const toImage = (fit, u, v) => [(u - fit.ox) / fit.s - 0.5, (v - fit.oy) / fit.s - 0.5];

  function drawCamera(view) {
    const fit = fitOf(view);
    view.fit = fit;
    const ctx = view.ctx;
    const cam = S.meta.cameras[view.c];
    ctx.fillStyle = '#000';
    ctx.fillRect(0, 0, view.canvas.width, view.canvas.height);
    const img = image(view.c, S.index);
    if (img && img.complete && img.naturalWidth > 0) {
      const [x0, y0] = [cam.crop[0] * fit.s + fit.ox, cam.crop[1] * fit.s + fit.oy];
      ctx.drawImage(img, x0, y0, cam.crop[2] * fit.s, cam.crop[3] * fit.s);
      view.shownFrame = frameOf(S.index);
      view.shownSource = img.src.split('/').slice(-2).join('/');
    } else {
      view.shownFrame = null;
      ctx.fillStyle = '#888';
      ctx.fillText(img && img.failed ? 'no footage for this frame' : 'loading...', 10, 30);
    }
    const dots = dotsAt(S.index, view.c);
    view.dots = dots;
    for (const d of dots) {
      const [u, v] = toCanvas(fit, d.x, d.y);
      ctx.beginPath();
      ctx.arc(u, v, 4, 0, 2 * Math.PI);
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = d.fixed ? FIXED_COLOUR : STATE_COLOURS[d.state];
      ctx.stroke();
      if (S.selected && S.selected.c === view.c && S.selected.marker === d.marker) {
        ctx.beginPath();
        ctx.arc(u, v, 8, 0, 2 * Math.PI);
        ctx.strokeStyle = '#fff';
        ctx.stroke();
      }
    }
  }
  function nearestDot(view, u, v, radius) {
    let best = null, bestD = radius;
    for (const d of view.dots || []) {
      const [du, dv] = toCanvas(view.fit, d.x, d.y);
      const dist = Math.hypot(du - u, dv - v);
      if (dist < bestD) { bestD = dist; best = d; }
    }
    return best;
  }
  function eventPos(view, e) {
    const r = view.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }
  function hideTooltip() { document.getElementById('tooltip').style.display = 'none'; }
  function onMouseMove(view, e) {
    const [u, v] = eventPos(view, e);
    if (S.drag && S.drag.view === view) {
      S.drag.moved = true;
      const [x, y] = toImage(view.fit, u, v);
      S.drag.dot.x = x; S.drag.dot.y = y;
      drawCamera(view);
      return;
    }
    const d = nearestDot(view, u, v, 8);
    const tip = document.getElementById('tooltip');
    if (!d) { hideTooltip(); return; }
    tip.textContent = d.marker + ' (' + (d.fixed ? 'fixed' : STATE_NAMES[d.state]) + ')';
    tip.style.left = (e.clientX + 12) + 'px';
    tip.style.top = (e.clientY + 12) + 'px';
    tip.style.display = 'block';
  }
  function onMouseDown(view, e) {
    const [u, v] = eventPos(view, e);
    const d = nearestDot(view, u, v, 8);
    if (d) {
      select({ c: view.c, marker: d.marker, x: d.x, y: d.y, frame: frameOf(S.index) });
      S.drag = { view, dot: d, moved: false };
    } else {
      const [x, y] = toImage(view.fit, u, v);
      select({ c: view.c, marker: '', x, y, frame: frameOf(S.index) });
    }
  }
  function onMouseUp(view) {
    const drag = S.drag;
    S.drag = null;
    if (!drag || !drag.moved) return;
    addFix({ frame: frameOf(S.index), camera: S.meta.cameras[view.c].name, marker: drag.dot.marker,
             action: 'move', x: drag.dot.x, y: drag.dot.y, to: '' });
  }
  function select(sel) {
    S.selected = sel;
    const cam = S.meta.cameras[sel.c].name;
    document.getElementById('selection').textContent = sel.marker
      ? 'Selected ' + sel.marker + ' in ' + cam + ' at frame ' + sel.frame + ' (' + sel.x.toFixed(1) + ', ' + sel.y.toFixed(1) + ' px).'
      : 'Selected an unnamed place in ' + cam + ' at frame ' + sel.frame + ' (' + sel.x.toFixed(1) + ', ' + sel.y.toFixed(1) + ' px): rename names the dot there.';
    if (sel.marker) document.getElementById('fix_marker').value = sel.marker;
    draw();
  }
  function fixFromSelection(action) {
    const sel = S.selected;
    if (!sel) { setStatus('select a dot first'); return; }
    const camera = S.meta.cameras[sel.c].name;
    const to = document.getElementById('fix_marker').value.trim();
    if (action === 'rename') {
      if (!S.meta.markers.includes(to)) { setStatus('unknown marker "' + to + '"'); return; }
      addFix({ frame: sel.frame, camera, marker: sel.marker, action, x: sel.x, y: sel.y, to });
      sel.marker = to;
    } else if (!sel.marker) {
      setStatus('select a named dot');
    } else if (action === 'unname') {
      addFix({ frame: sel.frame, camera, marker: sel.marker, action, x: sel.x, y: sel.y, to: '' });
    } else if (action === 'absent') {
      addFix({ frame: sel.frame, camera, marker: sel.marker, action, x: null, y: null, to: '' });
    }
  }
  function renderFixTable() {
    const body = document.querySelector('#fix_table tbody');
    body.innerHTML = '';
    S.fixes.forEach((f, n) => {
      const tr = document.createElement('tr');
      for (const v of [f.frame, f.camera, f.marker, f.action, csvNumber(f.x), csvNumber(f.y), f.to]) {
        const td = document.createElement('td');
        td.textContent = v;
        tr.appendChild(td);
      }
      const td = document.createElement('td');
      const del = document.createElement('button');
      del.textContent = 'remove';
      del.onclick = () => { S.fixes.splice(n, 1); saveFixes(); draw(); };
      td.appendChild(del);
      tr.appendChild(td);
      tr.onclick = (e) => { if (e.target !== del) setFrame(indexOf(f.frame)); };
      body.appendChild(tr);
    });
  }
  function exportFixes() {
    const blob = new Blob([fixesCsv()], { type: 'text/csv' });
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob);
    a.download = 'track_fixes.csv';
    document.body.appendChild(a);
    a.click();
    a.remove();
  }

  // ---------- the mesh ----------
  function buildMesh() {
    const box = document.getElementById('mesh_view');
    if (!window.THREE || !S.meta.mesh) {
      document.getElementById('mesh_info').textContent = S.meta.mesh ? 'three.js missing' : 'no solved mesh in the workspace';
      return;
    }
    const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    box.appendChild(renderer.domElement);
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0x101014);
    const camera = new THREE.PerspectiveCamera(30, 1, 1, 5000);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 0.65));
    const light = new THREE.DirectionalLight(0xffffff, 0.55);
    light.position.set(0.3, 0.5, 1);
    camera.add(light);
    scene.add(camera);
    const geometry = new THREE.BufferGeometry();
    const material = new THREE.MeshPhongMaterial({ color: 0xcfc4b8, vertexColors: THREE.NoColors, shininess: 12, side: THREE.DoubleSide });
    const mesh = new THREE.Mesh(geometry, material);
    scene.add(mesh);
    const bundleGeometry = new THREE.BufferGeometry();
    const bundles = new THREE.Points(bundleGeometry, new THREE.PointsMaterial({ size: 2.5, vertexColors: THREE.VertexColors, sizeAttenuation: true, depthTest: false }));
    bundles.renderOrder = 1;
    scene.add(bundles);
    const controls = new THREE.OrbitControls(camera, renderer.domElement);
    controls.addEventListener('change', () => renderMesh());
    S.three = { renderer, scene, camera, geometry, material, mesh, bundles, bundleGeometry, controls, shownFrame: null, ready: false };
  }
  function onTopology(t) {
    const T = S.three;
    if (!T) return;
    const V = S.meta.mesh.vertices;
    S.topology = { neutral: new Float32Array(t.neutral), nearest: new Uint16Array(t.nearest) };
    T.positions = new Float32Array(S.topology.neutral);
    T.colours = new Float32Array(3 * V).fill(0.8);
    T.geometry.setAttribute('position', new THREE.BufferAttribute(T.positions, 3));
    T.geometry.setAttribute('color', new THREE.BufferAttribute(T.colours, 3));
    T.geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(t.triangles), 1));
    T.geometry.computeVertexNormals();
    T.geometry.computeBoundingSphere();
    resetView();
    T.ready = true;
  }
  function resetView() {
    const T = S.three;
    if (!T || !T.geometry.boundingSphere) return;
    const sph = T.geometry.boundingSphere;
    T.controls.target.copy(sph.center);
    T.camera.position.set(sph.center.x, sph.center.y, sph.center.z + sph.radius * 3.6);
    T.camera.near = sph.radius * 0.05;
    T.camera.far = sph.radius * 20;
    T.camera.updateProjectionMatrix();
    T.controls.update();
    renderMesh();
  }
  // Viridis at t in [0, 1] (5 stops, linear between).
  const VIRIDIS = [[0.267, 0.005, 0.329], [0.230, 0.322, 0.546], [0.128, 0.567, 0.551], [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]];
  function viridis(t) {
    t = Math.min(1, Math.max(0, t)) * 4;
    const k = Math.min(3, Math.floor(t)), f = t - k;
    return VIRIDIS[k].map((a, n) => a + (VIRIDIS[k + 1][n] - a) * f);
  }
  function updateMesh() {
    const T = S.three;
    if (!T || !T.ready) return;
    const fd = frameData(S.index);
    const info = document.getElementById('mesh_info');
    if (!fd || !fd.mesh) {
      T.mesh.visible = false;
      T.shownFrame = null;
      info.textContent = fd ? 'no mesh at frame ' + frameOf(S.index) : 'loading...';
      renderMesh();
      return;
    }
    T.mesh.visible = true;
    const V = S.meta.mesh.vertices;
    const n = S.topology.neutral;
    const q = fd.mesh.displacement, s = fd.mesh.scale;
    for (let j = 0; j < 3 * V; ++j) T.positions[j] = n[j] + q[j] * s;
    T.geometry.attributes.position.needsUpdate = true;
    T.geometry.computeVertexNormals();
    const mode = document.getElementById('colour').value;
    const markerIndex = S.meta.mesh.bundle_markers;  // nearest-bundle index -> marker
    const residual = new Map(), outside = new Map();
    for (let j = 0; j < fd.bundles.length; j += 6) {
      residual.set(fd.bundles[j], fd.bundles[j + 4]);
      outside.set(fd.bundles[j], fd.bundles[j + 5]);
    }
    let label = 'frame ' + frameOf(S.index);
    if (mode === 'plain') {
      T.material.vertexColors = THREE.NoColors;
    } else {
      T.material.vertexColors = THREE.VertexColors;
      const top = mode === 'error' ? S.meta.mesh.error_max_mm : S.meta.mesh.residual_max_mm;
      for (let v = 0; v < V; ++v) {
        let t = 0;
        if (mode === 'error') t = fd.mesh.error ? fd.mesh.error[v] / 255 : 0;
        else if (mode === 'residual') t = (residual.get(markerIndex[S.topology.nearest[v]]) || 0) / top;
        else t = outside.get(markerIndex[S.topology.nearest[v]]) ? 1 : 0;
        const col = viridis(t);
        T.colours[3 * v] = col[0]; T.colours[3 * v + 1] = col[1]; T.colours[3 * v + 2] = col[2];
      }
      T.geometry.attributes.color.needsUpdate = true;
      label += mode === 'outside' ? ', yellow: nearest bundle outside its data' : ', 0-' + top + ' mm';
    }
    T.material.needsUpdate = true;
    // The bundles as points, coloured by their residual.
    const m = fd.bundles.length / 6;
    const pos = new Float32Array(3 * m), col = new Float32Array(3 * m);
    for (let j = 0; j < m; ++j) {
      pos.set([fd.bundles[6 * j + 1], fd.bundles[6 * j + 2], fd.bundles[6 * j + 3]], 3 * j);
      col.set(viridis(fd.bundles[6 * j + 4] / S.meta.mesh.residual_max_mm), 3 * j);
    }
    T.bundleGeometry.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    T.bundleGeometry.setAttribute('color', new THREE.BufferAttribute(col, 3));
    T.bundleGeometry.computeBoundingSphere();
    info.textContent = label;
    T.shownFrame = frameOf(S.index);
    renderMesh();
  }
  function renderMesh() {
    const T = S.three;
    if (!T) return;
    const box = document.getElementById('mesh_view');
    const w = box.clientWidth, h = box.clientHeight;
    const size = T.renderer.getSize(new THREE.Vector2());
    if (size.x !== w || size.y !== h) {
      T.renderer.setSize(w, h, false);
      T.camera.aspect = w / Math.max(1, h);
      T.camera.updateProjectionMatrix();
    }
    T.renderer.render(T.scene, T.camera);
  }

  // ---------- plots and warnings ----------
  const SERIES_COLOURS = ['#5fa8ff', '#ffb347', '#7ddc7d', '#ff6b6b', '#c792ea', '#e0e060'];
  function buildPlots() {
    const box = document.getElementById('plots');
    const W = 440, H = 150, L = 44, R = 8, T = 18, B = 22;
    S.plots = [];
    for (const p of S.meta.plots) {
      let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
      for (const s of p.series) {
        for (const [x, y] of s.points) {
          if (!isFinite(y)) continue;
          x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
        }
      }
      if (!isFinite(x0)) continue;
      if (p.zero_based) y0 = Math.min(0, y0);
      if (y1 <= y0) y1 = y0 + 1;
      if (x1 <= x0) x1 = x0 + 1;
      const sx = (x) => L + (x - x0) / (x1 - x0) * (W - L - R);
      const sy = (y) => H - B - (y - y0) / (y1 - y0) * (H - T - B);
      let svg = '<svg xmlns="http://www.w3.org/2000/svg" width="' + W + '" height="' + H + '">';
      svg += '<text x="' + L + '" y="12">' + escapeHtml(p.title) + '</text>';
      svg += '<text x="2" y="' + (T + 8) + '">' + fmt(y1) + '</text><text x="2" y="' + (H - B) + '">' + fmt(y0) + '</text>';
      svg += '<text x="' + L + '" y="' + (H - 6) + '">' + x0 + '</text><text x="' + (W - R - 30) + '" y="' + (H - 6) + '">' + x1 + '</text>';
      svg += '<rect x="' + L + '" y="' + T + '" width="' + (W - L - R) + '" height="' + (H - T - B) + '" fill="none" stroke="#444"/>';
      p.series.forEach((s, n) => {
        let d = '', pen = 'M';
        for (const [x, y] of s.points) {
          if (!isFinite(y)) { pen = 'M'; continue; }
          d += pen + sx(x).toFixed(1) + ' ' + sy(y).toFixed(1);
          pen = 'L';
        }
        svg += '<path d="' + d + '" fill="none" stroke-width="1.2" stroke="' + SERIES_COLOURS[n % 6] + '"/>';
        svg += '<text x="' + (L + 6 + 110 * n) + '" y="' + (T + 12) + '" style="fill:' + SERIES_COLOURS[n % 6] + '">' + escapeHtml(s.name) + '</text>';
      });
      svg += '<line class="cursor" x1="0" x2="0" y1="' + T + '" y2="' + (H - B) + '" stroke="#fff" stroke-width="1"/></svg>';
      const holder = document.createElement('div');
      holder.innerHTML = svg;
      const el = holder.firstChild;
      el.addEventListener('click', (e) => {
        const r = el.getBoundingClientRect();
        const f = Math.round(x0 + (e.clientX - r.left - L) / (W - L - R) * (x1 - x0));
        setFrame(indexOf(f));
      });
      box.appendChild(el);
      S.plots.push({ el, line: el.querySelector('line.cursor'), sx });
    }
  }
  function fmt(v) { return Math.abs(v) >= 100 ? v.toFixed(0) : v.toPrecision(3); }
  function escapeHtml(t) { return String(t).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]); }
  function buildWarnings() {
    const ul = document.getElementById('warnings');
    if (!S.meta.warnings.length) {
      const li = document.createElement('li');
      li.textContent = 'none';
      ul.appendChild(li);
    }
    for (const w of S.meta.warnings) {
      const li = document.createElement('li');
      li.textContent = w.stage + ': ' + w.text + ' ';
      const span = document.createElement('span');
      span.className = 'frames';
      for (const f of (w.frames || []).slice(0, 40)) {
        const a = document.createElement('a');
        a.textContent = f;
        a.onclick = (e) => { e.stopPropagation(); setFrame(indexOf(f)); };
        span.appendChild(a);
      }
      li.appendChild(span);
      if (w.frames && w.frames.length) li.onclick = () => setFrame(indexOf(w.frames[0]));
      ul.appendChild(li);
    }
  }

  // ---------- the cursor ----------
  function setStatus(text) { document.getElementById('status').textContent = text; }
  function setFrame(i) {
    if (!S.meta) return;
    i = Math.max(0, Math.min(S.meta.num_frames - 1, i | 0));
    S.index = i;
    document.getElementById('cursor').value = i;
    document.getElementById('frame_label').textContent = 'frame ' + frameOf(i);
    const k = chunkOf(i);
    trimChunks(k);
    loadChunk(k).then(() => { if (S.index === i) draw(); }).catch((e) => setStatus(e.message));
    loadChunk(k + 1).catch(() => {});
    prefetch(i);
    draw();
  }
  function draw() {
    for (const view of S.cams) drawCamera(view);
    updateMesh();
    for (const p of S.plots || []) {
      const x = p.sx(frameOf(S.index));
      p.line.setAttribute('x1', x);
      p.line.setAttribute('x2', x);
    }
    if (S.firstRender === null && S.cams.every((v) => v.shownFrame !== null) &&
        (!S.three || S.three.shownFrame !== null)) {
      S.firstRender = performance.now();  // since the navigation started
    }
  }
  function togglePlay() {
    S.playing = !S.playing;
    document.getElementById('play').innerHTML = S.playing ? '&#10074;&#10074;' : '&#9654;';
    clearInterval(S.timer);
    if (S.playing) {
      S.timer = setInterval(() => setFrame(S.index + 1 >= S.meta.num_frames ? 0 : S.index + 1), 1000 / S.meta.fps);
    }
  }
  function bindControls() {
    const cursor = document.getElementById('cursor');
    cursor.max = S.meta.num_frames - 1;
    cursor.addEventListener('input', () => setFrame(+cursor.value));
    document.getElementById('play').onclick = togglePlay;
    document.getElementById('reset_view').onclick = resetView;
    document.getElementById('colour').onchange = () => updateMesh();
    if (!S.meta.mesh || !S.meta.mesh.has_error) document.querySelector('#colour option[value=error]').disabled = true;
    document.getElementById('fix_rename').onclick = () => fixFromSelection('rename');
    document.getElementById('fix_unname').onclick = () => fixFromSelection('unname');
    document.getElementById('fix_absent').onclick = () => fixFromSelection('absent');
    document.getElementById('fix_export').onclick = exportFixes;
    document.getElementById('fix_clear').onclick = () => { S.fixes = []; saveFixes(); draw(); };
    const list = document.getElementById('marker_names');
    for (const m of S.meta.markers) {
      const o = document.createElement('option');
      o.value = m;
      list.appendChild(o);
    }
    document.addEventListener('keydown', (e) => {
      if (e.target.tagName === 'INPUT' && e.target.type !== 'range') return;
      if (e.key === 'ArrowRight') { setFrame(S.index + (e.shiftKey ? 10 : 1)); e.preventDefault(); }
      else if (e.key === 'ArrowLeft') { setFrame(S.index - (e.shiftKey ? 10 : 1)); e.preventDefault(); }
      else if (e.key === ' ') { togglePlay(); e.preventDefault(); }
    });
    window.addEventListener('resize', draw);
  }

  // ---------- entry points called by the data scripts ----------
  function meta(m) {
    S.meta = m;
    m.footage_frames = m.cameras.map((c) => new Set(c.frames));
    document.title = 'hmc review: ' + m.title;
    document.getElementById('title').textContent = 'hmc review: ' + m.title;
    loadFixes();
    if (m.fixes_used) {
      const rows = m.fixes_used.trim().split('\n').length - 1;
      document.getElementById('fixes_used').textContent =
        'This run tracked with ' + rows + ' fix' + (rows === 1 ? '' : 'es') + ' (WORK/track/track_fixes_used.csv).';
    }
    buildCameras();
    buildMesh();
    buildPlots();
    buildWarnings();
    bindControls();
    renderFixTable();
    // ?frame=N&colour=error: where the page opens (links, screenshots).
    const params = new URLSearchParams(location.search);
    const start = params.has('frame') ? indexOf(+params.get('frame')) : 0;
    if (params.has('colour')) document.getElementById('colour').value = params.get('colour');
    const ready = m.mesh && S.three ? loadScript('data/topology.js') : Promise.resolve();
    ready.then(() => setFrame(start)).catch((e) => setStatus(e.message))
      .then(() => { if (S.testMode) runTests(); });
  }
  function topology(t) {
    onTopology({ neutral: decodeBase64(t.neutral), triangles: decodeBase64(t.triangles), nearest: decodeBase64(t.nearest) });
  }
  // One chunk of frames: per frame its tracks (per camera a flat list of
  // marker, x, y, state), bundles (marker, x, y, z, residual, outside) and
  // the mesh record in the chunk's binary (docs/formats.md, "Review").
  // The binary is deflated (zlib): the browser's DecompressionStream
  // inflates it; the chunk is shown once it is.
  function inflate(buffer) {
    const stream = new Blob([buffer]).stream().pipeThrough(new DecompressionStream('deflate'));
    return new Response(stream).arrayBuffer();
  }
  function chunk(k, frames, meshBase64) {
    const V = S.meta.mesh ? S.meta.mesh.vertices : 0;
    const inflated = meshBase64 ? inflate(decodeBase64(meshBase64)) : Promise.resolve(null);
    S.inflating.set(k, inflated.then((buf) => {
      let offset = 0;
      for (const f of frames) {
        if (!f.has_mesh || !buf) continue;
        const scale = new DataView(buf, offset, 4).getFloat32(0, true);
        // int16 as two byte planes: the low bytes, then the high.
        const low = new Uint8Array(buf, offset + 4, 3 * V), high = new Uint8Array(buf, offset + 4 + 3 * V, 3 * V);
        const displacement = new Int16Array(3 * V);
        for (let j = 0; j < 3 * V; ++j) displacement[j] = low[j] | (high[j] << 8);
        offset += 4 + 6 * V;
        let error = null;
        if (S.meta.mesh.has_error) { error = new Uint8Array(buf, offset, V); offset += V; }
        offset = (offset + 3) & ~3;
        f.mesh = { scale, displacement, error };
      }
      S.chunks.set(k, { frames });
    }).catch((e) => { S.errors.push('cannot inflate chunk ' + k + ': ' + e); }));
  }

  // ---------- test mode (?test=1): scripted checks, results in the DOM ----------
  function waitFor(cond, ms) {
    return new Promise((resolve) => {
      const t0 = performance.now();
      (function poll() {
        if (cond()) resolve(true);
        else if (performance.now() - t0 > ms) resolve(false);
        else setTimeout(poll, 20);
      })();
    });
  }
  async function runTests() {
    const results = {};
    const out = document.getElementById('test_results');
    try {
      results.first_render_ok = await waitFor(() => S.firstRender !== null, 10000);
      results.first_render_ms = S.firstRender;
      if (/[?&]test=open/.test(location.search)) throw 'open only';  // ?test=open: the open alone, timed from outside
      const a = S.index;
      const meshA = S.three && S.three.positions ? Array.from(S.three.positions.slice(0, 3 * Math.min(2000, S.meta.mesh.vertices))) : [];
      const frameA = S.cams.map((v) => v.shownFrame);
      const b = Math.min(S.meta.num_frames - 1, a + Math.max(1, Math.floor(S.meta.num_frames / 2)));
      setFrame(b);
      results.moved_ok = await waitFor(() => S.cams.every((v) => v.shownFrame === frameOf(b)) &&
                                       (!S.three || S.three.shownFrame === frameOf(b)), 10000);
      results.footage_frames = [frameA, S.cams.map((v) => v.shownFrame)];
      // The images drawn (a canvas holding file:// pictures cannot be read back).
      results.footage_sources = S.cams.map((v) => v.shownSource);
      if (S.three && S.three.positions) {
        let move = 0;
        for (let j = 0; j < meshA.length; ++j) move = Math.max(move, Math.abs(S.three.positions[j] - meshA[j]));
        results.mesh_max_move_mm = move;
        // 50 vertices of the mesh drawn, for the test to compare with the
        // solve's mesh.pc2 (the chunks' decoding and rounding).
        const V = S.meta.mesh.vertices, vertices = [], positions = [];
        for (let k = 0; k < 50; ++k) {
          const v = Math.floor(k * (V - 1) / 49);
          vertices.push(v);
          for (let c = 0; c < 3; ++c) positions.push(S.three.positions[3 * v + c]);
        }
        results.mesh_sample = { frame: S.three.shownFrame, vertices, positions };
      }
      // A scripted rename: the first dot of the first camera at frame b is
      // renamed to the marker that camera's second dot has.
      S.fixes = [];
      const dots = dotsAt(S.index, 0);
      results.dots_at_cursor = dots.length;
      if (dots.length >= 2) {
        select({ c: 0, marker: dots[0].marker, x: dots[0].x, y: dots[0].y, frame: frameOf(S.index) });
        document.getElementById('fix_marker').value = dots[1].marker;
        fixFromSelection('rename');
        const after = dotsAt(S.index, 0);
        results.rename = { from: dots[0].marker, to: dots[1].marker, x: dots[0].x, y: dots[0].y,
                           frame: frameOf(S.index), camera: S.meta.cameras[0].name,
                           renamed_dot_found: after.some((d) => d.marker === dots[1].marker && d.fixed),
                           stored: JSON.parse(localStorage.getItem(storageKey()) || '[]').length };
      }
      results.csv = fixesCsv();
      S.fixes = [];
      saveFixes();
    } catch (e) {
      if (e !== 'open only') results.exception = String(e && e.stack || e);
    }
    results.errors = S.errors;
    out.setAttribute('data-done', '1');
    out.textContent = JSON.stringify(results);
  }
  // Every console error, uncaught exception and failed load, for the test
  // mode's report (a page that works must have none).
  const consoleError = console.error.bind(console);
  console.error = (...args) => { S.errors.push(args.map(String).join(' ')); consoleError(...args); };
  window.addEventListener('error', (e) => S.errors.push(String(e.message || ('cannot load ' + (e.target && (e.target.src || e.target.href))))), true);
  window.addEventListener('unhandledrejection', (e) => S.errors.push(String(e.reason)));

  return { meta, topology, chunk, setFrame, state: S };
})();
