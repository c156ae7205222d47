// mtlc preview page: draws the manikin from the IR (forward kinematics as in docs/ir.md),
// plays it on a timeline of task > action > element blocks, and shows per-frame figures.
// Its state is exposed as window.mtlcPreview so that tests can compare it with the IR.
(function () {
  "use strict";
  const BG = 0xf4f5f7;
  const state = {
    doc: null, time: 0, frame: 0, playing: false, speed: 1, generation: 0,
    joints: {}, points: {}, diagnostics: [], webgl: false, lastTick: null,
    // the view cone (docs/visibility.md): from the eye along the head's forward axis
    cone: { halfAngle: 30, visible: true, apex: null, axis: null },
  };

  // ---- forward kinematics (the rule of docs/ir.md) -------------------------------------------
  function axisAngle(a, t) {
    const [x, y, z] = a, s = Math.sin(t), c = 1 - Math.cos(t);
    // I + s K + c K^2, K the cross-product matrix of a (unit)
    return [
      [1 + c * (-z * z - y * y), -s * z + c * x * y, s * y + c * x * z],
      [s * z + c * x * y, 1 + c * (-z * z - x * x), -s * x + c * y * z],
      [-s * y + c * x * z, s * x + c * y * z, 1 + c * (-y * y - x * x)],
    ];
  }
  function quatMatrix(q) {
    const n = Math.hypot(q[0], q[1], q[2], q[3]) || 1;
    const w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    return [
      [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ];
  }
  function mul(A, B) {
    const C = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
    for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++)
      C[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
    return C;
  }
  function apply(R, v) {
    return [0, 1, 2].map((i) => R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2]);
  }
  function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }

  // The pose at a fractional frame: q and the root position interpolated linearly, the root
  // rotation normalised-linearly; at a whole frame it is that frame's pose exactly.
  function frameState(frames, t) {
    const times = frames.time, n = times.length;
    let i = 0;
    if (t <= times[0]) i = 0;
    else if (t >= times[n - 1]) i = n - 1;
    else { let lo = 0, hi = n - 1; while (hi - lo > 1) { const m = (lo + hi) >> 1; if (times[m] <= t) lo = m; else hi = m; } i = lo; }
    const j = Math.min(i + 1, n - 1);
    const f = j > i ? (t - times[i]) / (times[j] - times[i]) : 0;
    const lerp = (a, b) => a.map((v, k) => v + (b[k] - v) * f);
    let rot = frames.root_rotation[i];
    if (f > 0) {
      const b = frames.root_rotation[j], dot = rot.reduce((s, v, k) => s + v * b[k], 0);
      rot = rot.map((v, k) => v + ((dot < 0 ? -b[k] : b[k]) - v) * f);
    }
    return { index: f >= 0.5 ? j : i, q: f > 0 ? lerp(frames.q[i], frames.q[j]) : frames.q[i],
             root: f > 0 ? lerp(frames.root_position[i], frames.root_position[j]) : frames.root_position[i],
             rot: rot };
  }

  function jointTransforms(ir, fs) {
    const angle = {};
    ir.frames.dof_names.forEach((name, k) => { angle[name] = fs.q[k]; });
    const world = {};
    for (const joint of ir.manikin.joints) {
      let R, p;
      if (joint.parent === null) {
        R = quatMatrix(fs.rot);
        p = add(fs.root, apply(R, joint.offset));
      } else {
        const parent = world[joint.parent];
        R = parent.R;
        p = add(parent.p, apply(parent.R, joint.offset));
      }
      for (const dof of joint.dofs) R = mul(R, axisAngle(dof.axis, angle[dof.name]));
      world[joint.name] = { R, p };
    }
    return world;
  }

  function namedPoints(ir, world) {
    const out = {};
    for (const spec of [...ir.manikin.effectors, ...ir.manikin.contact_points]) {
      const w = world[spec.joint];
      if (w) out[spec.name] = add(w.p, apply(w.R, spec.offset));
    }
    return out;
  }

  // The eye point and the head's forward axis: the `gaze` effector and its direction.
  function eyeAndAxis(ir, world) {
    const gaze = ir.manikin.effectors.find((e) => e.name === "gaze" && e.direction);
    const w = gaze && world[gaze.joint];
    if (!w) return null;
    const axis = apply(w.R, gaze.direction), n = Math.hypot(...axis) || 1;
    return { apex: add(w.p, apply(w.R, gaze.offset)), axis: axis.map((v) => v / n) };
  }

  // ---- the 3D view (three.js) -----------------------------------------------------------------
  const view = { renderer: null, scene: null, camera: null, controls: null, body: null,
                 bones: [], sites: new Map(), goals: [], world: null };

  function initView() {
    const host = document.getElementById("view");
    let renderer;
    try {
      renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    } catch (err) {
      document.getElementById("no-webgl").hidden = false;
      return;
    }
    state.webgl = true;
    renderer.setPixelRatio(1);
    renderer.setClearColor(BG, 1);
    host.appendChild(renderer.domElement);
    const scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(2, 4, 3);
    scene.add(sun);
    const camera = new THREE.PerspectiveCamera(40, 1, 0.05, 100);
    const controls = new THREE.OrbitControls(camera, renderer.domElement);
    controls.enableDamping = false;
    controls.addEventListener("change", render);
    Object.assign(view, { renderer, scene, camera, controls });
    window.addEventListener("resize", resize);
    resize();
    initDragging();
  }

  function resize() {
    if (!view.renderer) return;
    const host = document.getElementById("view");
    const w = Math.max(host.clientWidth, 320), h = Math.max(host.clientHeight, 240);
    view.renderer.setSize(w, h, false);
    view.camera.aspect = w / h;
    view.camera.updateProjectionMatrix();
    render();
  }

  function clearGroup(group) {
    if (!group) return;
    view.scene.remove(group);
    group.traverse((o) => { if (o.geometry) o.geometry.dispose(); if (o.material) o.material.dispose(); });
  }

  // Capsules from each joint to its children (fixed lengths: offsets never change), and from
  // the wrists to the hands and the ankles to the toes.
  function buildBody(ir) {
    clearGroup(view.body);
    const group = new THREE.Group();
    const skin = new THREE.MeshStandardMaterial({ color: 0x5f7fae, roughness: 0.7 });
    const pairs = [];
    for (const j of ir.manikin.joints) if (j.parent !== null) pairs.push([j.parent, { joint: j.name }]);
    for (const spec of [...ir.manikin.effectors, ...ir.manikin.contact_points])
      if (/_(hand|toe)$/.test(spec.name)) pairs.push([spec.joint, { point: spec.name }]);
    view.bones = [];
    for (const [from, to] of pairs) {
      const radius = /thorax|lumbar|pelvis/.test(to.joint || "") ? 0.07 : /head|neck/.test(to.joint || "") ? 0.05 : 0.035;
      const mesh = new THREE.Mesh(new THREE.CapsuleGeometry(radius, 1, 4, 10), skin);
      group.add(mesh);
      view.bones.push({ from, to, mesh });
    }
    const head = new THREE.Mesh(new THREE.SphereGeometry(0.1, 20, 14), skin);
    group.add(head);
    view.head = head;
    view.cone = buildCone(state.cone.halfAngle);
    group.add(view.cone);
    view.scene.add(group);
    view.body = group;
  }

  // A translucent cone, apex at the origin, opening along -Y, 1.2 m long.
  const CONE_LENGTH = 1.2;
  function buildCone(halfAngleDeg) {
    const radius = CONE_LENGTH * Math.tan((Math.min(halfAngleDeg, 80) * Math.PI) / 180);
    const geometry = new THREE.ConeGeometry(radius, CONE_LENGTH, 32, 1, true);
    geometry.translate(0, -CONE_LENGTH / 2, 0);
    const cone = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({
      color: 0xf2c230, transparent: true, opacity: 0.18, side: THREE.DoubleSide, depthWrite: false,
    }));
    cone.renderOrder = 1;
    return cone;
  }

  function buildWorld(ir) {
    clearGroup(view.world);
    const group = new THREE.Group();
    const ground = ir.scene.ground || 0;
    const floor = new THREE.Mesh(new THREE.PlaneGeometry(12, 12),
      new THREE.MeshLambertMaterial({ color: 0xd9dce2 }));
    floor.rotation.x = -Math.PI / 2;
    floor.position.y = ground - 0.001;
    group.add(floor);
    const grid = new THREE.GridHelper(12, 24, 0x9aa1ad, 0xbfc4cc);
    grid.position.y = ground;
    group.add(grid);
    view.sites = new Map();
    for (const site of ir.scene.sites) {
      const mesh = new THREE.Mesh(new THREE.SphereGeometry(0.025, 16, 10),
        new THREE.MeshStandardMaterial({ color: 0xf08a24 }));
      mesh.position.set(...site.position);
      mesh.userData.site = site.name;
      group.add(mesh);
      view.sites.set(site.name, mesh);
    }
    view.goals = [];
    for (const goal of ir.goals) {
      if (goal.phase !== "TO" || !goal.position) continue;
      const ring = new THREE.Mesh(new THREE.SphereGeometry(0.04, 12, 8),
        new THREE.MeshBasicMaterial({ color: 0x2e9d5b, wireframe: true }));
      ring.position.set(...goal.position);
      group.add(ring);
      view.goals.push({ goal, mesh: ring });
    }
    buildModels(group, state.doc);
    view.scene.add(group);
    view.world = group;
  }

  // the scene's models as the compile read them (positions in m, flat; triangles, flat)
  const MODEL_COLOUR = 0x9aa3ad, CLASH_COLOUR = 0xd0402a;
  function buildModels(group, doc) {
    view.models = new Map();
    view.held = [];
    for (const model of (doc && doc.models) || []) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute("position", new THREE.Float32BufferAttribute(model.positions, 3));
      geometry.setIndex(model.indices);
      geometry.computeVertexNormals();
      const material = new THREE.MeshStandardMaterial({
        color: MODEL_COLOUR, roughness: 0.8, transparent: true, opacity: 0.6, side: 2,
        depthWrite: false,
      });
      const mesh = new THREE.Mesh(geometry, material);
      mesh.userData.model = model.name;
      group.add(mesh);
      view.models.set(model.name, mesh);
      // a part a hand holds: placed on every frame where the IR's holds put it
      if (model.placement) {
        mesh.matrixAutoUpdate = false;
        view.held.push({ name: model.name, mesh, placement: model.placement });
      }
    }
  }

  // each held part where its placement on frame i puts it (3 x 4 rows, flat)
  function placeHeld(i) {
    for (const { mesh, placement } of view.held || []) {
      const m = placement[Math.min(Math.max(i, 0), placement.length - 1)];
      mesh.matrix.set(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11],
        0, 0, 0, 1);
      mesh.matrixWorldNeedsUpdate = true;
    }
  }

  // the frame's smallest clearance: its text, and the model it is to tinted when inside
  function clearanceAt(doc, i) {
    const c = doc.clearance, v = doc.figures.clearance ? doc.figures.clearance[i] : null;
    if (!c || v === null || v === undefined) return null;
    return { value: v, part: c.parts[c.part[i]], mesh: c.meshes[c.mesh[i]] };
  }
  function showClearance(doc, i) {
    const rows = document.querySelectorAll(".geometry");
    rows.forEach((r) => { r.hidden = !doc.figures.clearance; });
    const now = clearanceAt(doc, i), el = document.getElementById("fig-clearance");
    state.clearance = now;
    for (const [name, mesh] of view.models || []) {
      const clash = now !== null && now.value < 0 &&
        (now.mesh === name || now.part === `held part ${name}`);
      mesh.material.color.setHex(clash ? CLASH_COLOUR : MODEL_COLOUR);
    }
    if (!now) { el.textContent = "–"; el.className = ""; return; }
    el.textContent = `${(now.value * 1000).toFixed(0)} mm (${now.part} · ${now.mesh})`;
    el.className = now.value < 0 ? "bad" : "";
  }

  function frameCamera(ir) {
    const rp = ir.frames.root_position;
    let cx = 0, cz = 0;
    for (const p of rp) { cx += p[0]; cz += p[2]; }
    cx /= rp.length; cz /= rp.length;
    const g = ir.scene.ground || 0;
    view.controls.target.set(cx, g + 0.9, cz);
    view.camera.position.set(cx + 2.6, g + 2.0, cz + 3.4);
    view.controls.update();
  }

  const Y = new THREE.Vector3(0, 1, 0), DOWN = new THREE.Vector3(0, -1, 0);
  function drawPose(world, points) {
    if (!state.webgl) return;
    const a = new THREE.Vector3(), b = new THREE.Vector3(), d = new THREE.Vector3();
    for (const bone of view.bones) {
      const p0 = world[bone.from].p, p1 = bone.to.joint ? world[bone.to.joint].p : points[bone.to.point];
      a.set(...p0); b.set(...p1);
      d.subVectors(b, a);
      const len = d.length();
      bone.mesh.visible = len > 1e-4;
      if (!bone.mesh.visible) continue;
      bone.mesh.position.addVectors(a, b).multiplyScalar(0.5);
      bone.mesh.quaternion.setFromUnitVectors(Y, d.normalize());
      bone.mesh.scale.set(1, len, 1);
    }
    const head = world.head;
    if (head) view.head.position.set(...add(head.p, apply(head.R, [0, 0.09, 0.01])));
    if (view.cone) {
      view.cone.visible = state.cone.visible && state.cone.apex !== null;
      if (view.cone.visible) {
        view.cone.position.set(...state.cone.apex);
        view.cone.quaternion.setFromUnitVectors(DOWN, new THREE.Vector3(...state.cone.axis));
      }
    }
    for (const { goal, mesh } of view.goals) mesh.visible = state.time >= goal.t_start - 1e-6;
    placeHeld(state.frame);
    render();
  }

  function render() {
    if (view.renderer) view.renderer.render(view.scene, view.camera);
  }

  // ---- timeline and figures -------------------------------------------------------------------
  const LANE_H = 16;
  function buildTimeline(doc) {
    const host = document.getElementById("timeline");
    host.querySelectorAll(".block").forEach((el) => el.remove());
    const duration = duration_(doc);
    const lanes = [0, 0, 0];
    for (const b of doc.blocks) lanes[b.level] = Math.max(lanes[b.level], b.lane + 1);
    const top = [2, 2 + lanes[0] * LANE_H + 2, 4 + (lanes[0] + lanes[1]) * LANE_H + 2];
    host.style.height = `${top[2] + lanes[2] * LANE_H + 4}px`;
    const tip = document.getElementById("tooltip");
    for (const b of doc.blocks) {
      const el = document.createElement("div");
      el.className = `block level-${b.level}`;
      el.style.left = `${(100 * b.start) / duration}%`;
      el.style.width = `calc(${(100 * (b.end - b.start)) / duration}% - 1px)`;
      el.style.top = `${top[b.level] + b.lane * LANE_H}px`;
      el.textContent = b.label;
      el.dataset.start = b.start;
      el.dataset.kind = b.kind;
      el.addEventListener("click", () => { setTime(b.start); });
      el.addEventListener("mouseenter", () => {
        const src = b.source.file === b.origin.file && b.source.line === b.origin.line ? "" :
          `\n${b.source.file}:${b.source.line}  ${b.source.text}`;
        tip.textContent = `${b.kind} ${b.path}  [${b.start.toFixed(2)}–${b.end.toFixed(2)} s]\n` +
          `${b.origin.file}:${b.origin.line}  ${b.origin.text}${src}`;
        tip.hidden = false;
      });
      el.addEventListener("mousemove", (ev) => {
        tip.style.left = `${Math.min(ev.clientX + 12, window.innerWidth - 420)}px`;
        tip.style.top = `${ev.clientY - 56}px`;
      });
      el.addEventListener("mouseleave", () => { tip.hidden = true; });
      host.appendChild(el);
    }
  }

  function duration_(doc) {
    const t = doc.ir.frames.time;
    return Math.max(t[t.length - 1], 1e-6);
  }

  const FIGURES = {
    contact_error: (v) => `${(v * 1000).toFixed(2)} mm`,
    com_margin: (v) => `${(v * 100).toFixed(1)} cm`,
    penetration: (v) => `${(v * 1000).toFixed(2)} mm`,
  };
  function showFigures(doc, i) {
    const figs = doc.figures;
    for (const [name, fmt] of Object.entries(FIGURES)) {
      const v = figs[name][i], el = document.getElementById(`fig-${name}`);
      el.textContent = v === null ? "–" : fmt(v);
      el.className = v !== null && ((name === "com_margin" && v < 0) || (name !== "com_margin" && v > 0.001)) ? "bad" : "";
    }
    const rula = figs.rula[i], worst = figs.rula_worst_so_far[i];
    const el = document.getElementById("fig-rula");
    el.textContent = rula === null ? "–" : `${rula} (${worst})`;
    el.className = worst >= 5 ? "bad" : "";
    showClearance(doc, i);
    document.querySelectorAll(".spark").forEach((c) => {
      if (figs[c.dataset.figure]) drawSpark(c, figs[c.dataset.figure], i);
    });
  }

  function drawSpark(canvas, values, cursor) {
    const g = canvas.getContext("2d"), w = canvas.width, h = canvas.height;
    g.clearRect(0, 0, w, h);
    const finite = values.filter((v) => v !== null);
    if (!finite.length) return;
    let lo = Math.min(0, ...finite), hi = Math.max(...finite);
    if (hi - lo < 1e-12) hi = lo + 1;
    const x = (k) => (k / Math.max(values.length - 1, 1)) * (w - 1);
    const y = (v) => h - 2 - ((v - lo) / (hi - lo)) * (h - 4);
    g.strokeStyle = "#6f8fc0"; g.beginPath();
    let pen = false;
    values.forEach((v, k) => {
      if (v === null) { pen = false; return; }
      if (pen) g.lineTo(x(k), y(v)); else g.moveTo(x(k), y(v));
      pen = true;
    });
    g.stroke();
    g.fillStyle = "#e0452b"; g.fillRect(x(cursor) - 0.5, 0, 1.5, h);
  }

  // ---- time -----------------------------------------------------------------------------------
  function setTime(t) {
    const doc = state.doc;
    if (!doc) return;
    const d = duration_(doc);
    state.time = Math.min(Math.max(Number(t) || 0, doc.ir.frames.time[0]), d);
    const fs = frameState(doc.ir.frames, state.time);
    state.frame = fs.index;
    const world = jointTransforms(doc.ir, fs);
    state.points = namedPoints(doc.ir, world);
    state.joints = {};
    for (const [name, w] of Object.entries(world)) state.joints[name] = w.p.slice();
    const sight = eyeAndAxis(doc.ir, world);
    state.cone.apex = sight ? sight.apex : null;
    state.cone.axis = sight ? sight.axis : null;
    drawPose(world, state.points);
    document.getElementById("cursor").style.left = `${(100 * state.time) / d}%`;
    document.getElementById("scrub").value = String(Math.round((1000 * state.time) / d));
    document.getElementById("clock").textContent = `${state.time.toFixed(2)} / ${d.toFixed(2)} s`;
    document.getElementById("fig-time").textContent = state.time.toFixed(2);
    showFigures(doc, state.frame);
  }

  function setFrame(i) {
    const t = state.doc.ir.frames.time;
    setTime(t[Math.min(Math.max(i | 0, 0), t.length - 1)]);
  }

  function tick(now) {
    if (state.playing && state.doc) {
      const dt = state.lastTick === null ? 0 : (now - state.lastTick) / 1000;
      let t = state.time + dt * state.speed;
      if (t > duration_(state.doc)) t = 0;
      setTime(t);
    }
    state.lastTick = state.playing ? now : null;
    requestAnimationFrame(tick);
  }

  function play() { state.playing = true; document.getElementById("play").textContent = "Pause"; }
  function pause() { state.playing = false; document.getElementById("play").textContent = "Play"; }
  function setSpeed(s) { state.speed = Number(s) || 1; document.getElementById("speed").value = String(s); }

  // ---- loading a motion ---------------------------------------------------------------------
  function load(doc) {
    const first = state.doc === null;
    state.doc = doc;
    state.generation += 1;
    const ir = doc.ir;
    if (doc.view_cone) state.cone.halfAngle = doc.view_cone.half_angle_deg;
    const title = ir.source.title || ir.source.task;
    document.getElementById("title").textContent = title;
    document.title = `${title} – mtlc preview`;
    document.getElementById("source-file").textContent = `${ir.source.file} › ${ir.source.task}`;
    if (state.webgl) {
      buildBody(ir);
      buildWorld(ir);
      if (first) frameCamera(ir);
    }
    buildTimeline(doc);
    setTime(first ? 0 : state.time);
  }

  function showDiagnostics(items) {
    state.diagnostics = items || [];
    const box = document.getElementById("diagnostics");
    box.hidden = state.diagnostics.length === 0;
    box.textContent = state.diagnostics.map((d) =>
      `${d.severity || "error"}[${d.code}] ${d.file}:${d.line}:${d.column}: ${d.message}`).join("\n");
  }

  function status(text) { document.getElementById("status").textContent = text; }

  // ---- serve mode: frames streamed by the server, sites dragged back to it -------------------
  function connect() {
    const events = new EventSource("/events");
    events.addEventListener("motion", (ev) => {
      load(JSON.parse(ev.data));
      showDiagnostics([]);
      status(`motion ${state.generation} received`);
    });
    events.addEventListener("diagnostics", (ev) => {
      showDiagnostics(JSON.parse(ev.data).diagnostics);
      status("recompile failed; showing the last good motion");
    });
    events.onerror = () => status("connection lost; retrying…");
  }

  async function moveSite(name, position) {
    const reply = await fetch("/site", {
      method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ site: name, position: position.map(Number) }),
    });
    const body = await reply.json().catch(() => ({}));
    if (!reply.ok) status(`site not moved: ${body.error || reply.status}`);
    return { status: reply.status, body };
  }

  function initDragging() {
    const canvas = view.renderer.domElement, ray = new THREE.Raycaster();
    const plane = new THREE.Plane(), hit = new THREE.Vector3(), ndc = new THREE.Vector2();
    let dragged = null;
    const pick = (ev) => {
      const r = canvas.getBoundingClientRect();
      ndc.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
      ray.setFromCamera(ndc, view.camera);
    };
    canvas.addEventListener("pointerdown", (ev) => {
      if (!window.MTLC_SERVE) return;
      pick(ev);
      const hits = ray.intersectObjects([...view.sites.values()]);
      if (!hits.length) return;
      dragged = hits[0].object;
      view.controls.enabled = false;
      const normal = view.camera.getWorldDirection(new THREE.Vector3()).negate();
      plane.setFromNormalAndCoplanarPoint(normal, dragged.position);
      canvas.setPointerCapture(ev.pointerId);
    });
    canvas.addEventListener("pointermove", (ev) => {
      if (!dragged) return;
      pick(ev);
      if (ray.ray.intersectPlane(plane, hit)) { dragged.position.copy(hit); render(); }
    });
    canvas.addEventListener("pointerup", () => {
      if (!dragged) return;
      const p = dragged.position;
      moveSite(dragged.userData.site, [p.x, p.y, p.z]);
      dragged = null;
      view.controls.enabled = true;
    });
  }

  // Where a site is drawn, in the page's CSS pixels (for tests that drag it like a user).
  function siteScreenPosition(name) {
    const mesh = view.sites.get(name);
    if (!mesh) return null;
    const r = view.renderer.domElement.getBoundingClientRect();
    const v = mesh.position.clone().project(view.camera);
    return [r.left + ((v.x + 1) / 2) * r.width, r.top + ((1 - v.y) / 2) * r.height];
  }

  function setViewCone(visible) {
    state.cone.visible = Boolean(visible);
    const box = document.getElementById("view-cone");
    if (box) box.checked = state.cone.visible;
    if (state.doc) setTime(state.time);
  }

  // The cone's toggle: a checkbox next to the speed, and the `v` key.
  function initConeToggle() {
    const label = document.createElement("label");
    label.title = "The view cone: sites outside it are out of sight (docs/visibility.md, MT0607)";
    const box = document.createElement("input");
    box.type = "checkbox"; box.id = "view-cone"; box.checked = state.cone.visible;
    box.addEventListener("change", () => setViewCone(box.checked));
    label.append(box, " view cone");
    document.getElementById("clock").before(label);
    document.addEventListener("keydown", (ev) => {
      if (ev.key === "v" && !(ev.target instanceof HTMLInputElement && ev.target.type !== "checkbox")
          && !(ev.target instanceof HTMLSelectElement)) setViewCone(!state.cone.visible);
    });
  }

  // ---- start --------------------------------------------------------------------------------
  document.getElementById("play").addEventListener("click", () => (state.playing ? pause() : play()));
  document.getElementById("speed").addEventListener("change", (ev) => setSpeed(ev.target.value));
  document.getElementById("scrub").addEventListener("input", (ev) => {
    if (state.doc) setTime((Number(ev.target.value) / 1000) * duration_(state.doc));
  });
  initView();
  initConeToggle();
  window.mtlcPreview = {
    get ready() { return state.doc !== null; },
    get time() { return state.time; },
    get frame() { return state.frame; },
    get playing() { return state.playing; },
    get speed() { return state.speed; },
    get generation() { return state.generation; },
    get joints() { return state.joints; },
    get points() { return state.points; },
    get diagnostics() { return state.diagnostics; },
    get webgl() { return state.webgl; },
    get models() {
      return [...(view.models || new Map()).entries()].map(([name, mesh]) => ({
        name, triangles: mesh.geometry.index.count / 3,
        clash: mesh.material.color.getHex() === CLASH_COLOUR,
      }));
    },
    get clearance() { return state.clearance; },
    // each held part's name and the centre of its box where it is drawn now (world, m)
    get heldParts() {
      return (view.held || []).map(({ name, mesh }) => {
        mesh.updateMatrixWorld(true);
        mesh.geometry.computeBoundingBox();
        const c = mesh.geometry.boundingBox.getCenter(new THREE.Vector3());
        c.applyMatrix4(mesh.matrixWorld);
        return { name, centre: [c.x, c.y, c.z] };
      });
    },
    setModelsVisible(visible) {
      for (const mesh of (view.models || new Map()).values()) mesh.visible = Boolean(visible);
      render();
    },
    get document() { return state.doc; },
    get viewCone() {
      const c = state.cone;
      return { halfAngle: c.halfAngle, visible: c.visible, apex: c.apex, axis: c.axis };
    },
    setTime, setViewCone, setFrame, play, pause, setSpeed, moveSite, siteScreenPosition,
  };
  const embedded = JSON.parse(document.getElementById("mtlc-data").textContent);
  if (embedded) load(embedded);
  if (window.MTLC_SERVE) connect();
  requestAnimationFrame(tick);
})();
