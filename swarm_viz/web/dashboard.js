// Swarm Workbench dashboard: plain JS and canvas, no library, nothing from the internet.
// The messages it reads (hello, frame, robot) are defined in swarm_viz/fleet_view.py.
"use strict";
(() => {
  const STATE_COLOR = {
    IDLE: "#999", PLANNING: "#99e", DRIVING: "#2978f2", HOLDING: "#ff8c00",
    RECOVERING: "#a64dd9", SUCCEEDED: "#33bf4d", ABORTED: "#e62626", CANCELED: "#808080",
  };
  const WS_COLOR = { free: "#33bf4d", occupied: "#ffbf00", held: "#e62626" };
  const ROBOT_PAGE = location.pathname.startsWith("/robot/")
    ? decodeURIComponent(location.pathname.slice("/robot/".length)) : null;

  const S = {
    hello: null, frame: null, paths: {}, robot: {}, selected: ROBOT_PAGE, ws: null,
    frames: 0, recv: [], drawn: 0, textAt: -1e9, scanPoints: 0, mapImg: null,
    view: null, // main map: {scale [px/m], x0, y0 (map point at the canvas centre)}
    zoom: 60, // robot view [px/m]
  };

  const $ = (id) => document.getElementById(id);
  const mapCanvas = $("map");
  const robotCanvas = $("robotview");

  // ------------------------------------------------------------------ connection
  function connect() {
    const q = ROBOT_PAGE ? `?robot=${encodeURIComponent(ROBOT_PAGE)}` : "";
    const ws = new WebSocket(`ws://${location.host}/ws${q}`);
    S.ws = ws;
    ws.onopen = () => { $("conn").textContent = "live"; sendWatch(); };
    ws.onclose = () => {
      $("conn").textContent = "disconnected (retrying)";
      S.ws = null;
      setTimeout(connect, 1000);
    };
    ws.onmessage = (ev) => {
      const msg = JSON.parse(ev.data);
      if (msg.type === "hello") onHello(msg);
      else if (msg.type === "frame") onFrame(msg);
      else if (msg.type === "robot") onRobot(msg);
    };
  }

  function sendWatch() {
    if (S.ws && S.ws.readyState === WebSocket.OPEN) {
      S.ws.send(JSON.stringify({ watch: S.selected ? [S.selected] : [] }));
    }
  }

  function onHello(msg) {
    S.hello = msg;
    S.paths = {};
    S.robot = {};
    $("title").textContent = `Swarm Workbench · ${msg.world}`;
    if (!S.mapImg) {
      const img = new Image();
      img.onload = () => { S.mapImg = img; draw(); };
      img.src = msg.map.url;
    }
    if (ROBOT_PAGE) {
      document.body.classList.add("robot-page");
      document.title = `${ROBOT_PAGE} · Swarm Workbench`;
      select(ROBOT_PAGE);
    }
    resize();
  }

  function onFrame(msg) {
    S.frame = msg;
    for (const [i, path] of Object.entries(msg.paths)) S.paths[i] = path;
    S.frames += 1;
    const now = performance.now();
    S.recv.push(now);
    while (S.recv.length && now - S.recv[0] > 5000) S.recv.shift();
    schedule();
  }

  function onRobot(msg) {
    const prev = S.robot[msg.robot] || {};
    S.robot[msg.robot] = {
      status: msg.status, message: msg.message,
      scan: msg.scan !== null ? msg.scan : prev.scan,
    };
    schedule();
  }

  // A frame and the robot messages sent with it are shown in one animation frame: the page is
  // laid out, painted and composited once per server frame instead of once per message. The
  // text (KPIs, the status table) is rewritten at most every TEXT_PERIOD_MS, the latest values
  // always shown in the end: a text change re-lays out and repaints the page, and at 6 frames a
  // second it cost headless Chromium about 1 % of a core of its 9-11 % (100 robots, a captured
  // run replayed, 25 s: 8.5 -> 7.8 % whole floor, 10.7 -> 9.5 % with a robot's view).
  let scheduled = false, textTimer = null;
  const TEXT_PERIOD_MS = 480;
  function schedule() {
    if (scheduled) return;
    scheduled = true;
    requestAnimationFrame((now) => {
      scheduled = false;
      if (now - S.textAt >= TEXT_PERIOD_MS) {
        S.textAt = now;
        if (S.frame) showKpis(S.frame.kpi);
        showStatus();
      } else if (textTimer === null) {
        textTimer = setTimeout(() => { textTimer = null; schedule(); },
          TEXT_PERIOD_MS - (now - S.textAt));
      }
      draw();
    });
  }

  function fps() {
    const r = S.recv;
    if (r.length < 2) return 0;
    return (r.length - 1) / ((r[r.length - 1] - r[0]) / 1000);
  }

  // Text is written only when it changed: a write re-lays out and repaints the page. Measured
  // with headless Chromium (software raster), 100 robots, 6 frames a second: rewriting the KPIs
  // every frame cost about 3 % of a core and rebuilding the status table 5 %.
  function setText(el, text) {
    if (el.textContent !== text) el.textContent = text;
  }

  function showKpis(k) {
    const fmt = (v, d) => (v === null || v === undefined) ? "-" : (d === undefined ? String(v) : v.toFixed(d));
    setText($("kpi-sim_time_s"), fmt(k.sim_time_s, 1));
    setText($("kpi-rtf"), fmt(k.rtf, 2));
    setText($("kpi-tasks"), fmt(k.tasks));
    setText($("kpi-throughput_per_hour"), fmt(k.throughput_per_hour, 1));
    setText($("kpi-goals_aborted"), fmt(k.goals_aborted));
    setText($("kpi-collisions"), fmt(k.collisions));
    setText($("kpi-late_ticks"), fmt(k.late_ticks));
    setText($("kpi-fps"), fps().toFixed(1));
  }

  // ------------------------------------------------------------------ selection
  function select(ns) {
    S.selected = ns;
    const panel = $("panel");
    panel.hidden = !ns;
    if (ns) {
      $("panel-name").textContent = ns;
      $("panel-link").href = `/robot/${encodeURIComponent(ns)}`;
    }
    sendWatch();
    resize();
    showStatus();
  }

  function selectedIndex() {
    return S.hello && S.selected ? S.hello.robots.indexOf(S.selected) : -1;
  }

  // The rows are kept and their cells rewritten only where a value changed.
  function showStatus() {
    const i = selectedIndex();
    const table = $("status");
    if (i < 0) {
      if (table.rows.length) table.textContent = "";
      return;
    }
    const r = S.robot[i];
    const pose = S.frame && S.frame.robots[i];
    const rows = [];
    if (pose) rows.push(["pose", `${pose[0].toFixed(2)}, ${pose[1].toFixed(2)}, ${(pose[2] * 180 / Math.PI).toFixed(0)}°`]);
    if (r && r.status) for (const [k, v] of Object.entries(r.status)) rows.push([k, v]);
    else rows.push(["nav_status", r ? "none yet" : "waiting"]);
    while (table.rows.length > rows.length) table.deleteRow(-1);
    rows.forEach(([k, v], n) => {
      const tr = n < table.rows.length ? table.rows[n] : table.insertRow();
      if (!tr.cells.length) { tr.insertCell(); tr.insertCell(); }
      setText(tr.cells[0], k);
      setText(tr.cells[1], String(v));
    });
  }

  // ------------------------------------------------------------------ geometry
  function mapExtent() {
    const m = S.hello.map;
    return { x0: m.origin[0], y0: m.origin[1], w: m.width * m.resolution, h: m.height * m.resolution };
  }

  function fitView() {
    const e = mapExtent();
    const scale = Math.min(mapCanvas.width / e.w, mapCanvas.height / e.h) * 0.98;
    S.view = { scale, cx: e.x0 + e.w / 2, cy: e.y0 + e.h / 2 };
  }

  function transformFor(canvas, view) {
    const { scale, cx, cy } = view;
    const ox = canvas.width / 2, oy = canvas.height / 2;
    return {
      scale,
      px: (x) => ox + (x - cx) * scale,
      py: (y) => oy - (y - cy) * scale,
      inv: (u, v) => [cx + (u - ox) / scale, cy - (v - oy) / scale],
    };
  }

  function resize() {
    const dpr = 1;
    if (!ROBOT_PAGE) {
      const r = mapCanvas.getBoundingClientRect();
      mapCanvas.width = Math.max(100, Math.floor(r.width * dpr));
      mapCanvas.height = Math.max(100, Math.floor(r.height * dpr));
    } else {
      const r = robotCanvas.getBoundingClientRect();
      robotCanvas.width = Math.max(100, Math.floor(r.width));
      robotCanvas.height = Math.max(100, Math.floor(r.height));
    }
    if (S.hello && !S.userView) fitView();
    draw();
  }

  // ------------------------------------------------------------------ drawing
  function label(ctx, text, u, v) {  // dark text with a light halo: readable on floor and walls
    ctx.lineWidth = 3;
    ctx.strokeStyle = "rgba(255, 255, 255, 0.85)";
    ctx.strokeText(text, u, v);
    ctx.fillStyle = "#1d2024";
    ctx.fillText(text, u, v);
  }

  function drawMap(ctx, T) {
    if (!S.mapImg) return;
    const e = mapExtent();
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(S.mapImg, T.px(e.x0), T.py(e.y0 + e.h), e.w * T.scale, e.h * T.scale);
  }

  // The map and workstations' layer changes only with the view and the workstations' states.
  // The main map has it on a canvas of its own underneath (redrawn only when it changes; the
  // robots' canvas above is cleared, not repainted, each frame: copying a full-size layer was
  // most of the page's cost); the robot view, which follows its robot, draws it every frame.
  function drawBackground(canvas, ctx, T) {
    const under = canvas === mapCanvas ? $("mapbg") : null;
    if (!under) {
      ctx.fillStyle = "#111";
      ctx.fillRect(0, 0, canvas.width, canvas.height);
      drawMap(ctx, T);
      drawWorkstations(ctx, T);
      return;
    }
    const key = [canvas.width, canvas.height, T.px(0), T.py(0), T.scale, !!S.mapImg,
      S.frame ? S.frame.ws.join() : ""].join();
    if (under._key !== key) {
      under._key = key;
      under.width = canvas.width;
      under.height = canvas.height;
      const b = under.getContext("2d");
      b.fillStyle = "#111";
      b.fillRect(0, 0, canvas.width, canvas.height);
      drawMap(b, T);
      drawWorkstations(b, T);
    }
    ctx.clearRect(0, 0, canvas.width, canvas.height);
  }

  function drawWorkstations(ctx, T) {
    const f = S.frame;
    S.hello.workstations.forEach((w, k) => {
      const state = f ? f.ws[k] : "free";
      const s = Math.max(0.4 * T.scale, 6);
      ctx.fillStyle = WS_COLOR[state] || "#777";
      ctx.globalAlpha = 0.8;
      ctx.fillRect(T.px(w.x) - s / 2, T.py(w.y) - s / 2, s, s);
      ctx.globalAlpha = 1;
      ctx.strokeStyle = "#ff8c00";
      ctx.lineWidth = 1;
      for (const [hx, hy] of w.holding) {
        ctx.beginPath();
        ctx.arc(T.px(hx), T.py(hy), Math.max(0.12 * T.scale, 2), 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.font = `${Math.max(10, Math.min(14, 0.3 * T.scale))}px sans-serif`;
      label(ctx, w.name, T.px(w.x) + s / 2 + 2, T.py(w.y) - s / 2);
    });
  }

  function drawPath(ctx, T, path, color, width) {
    if (!path || path.length < 2) return;
    ctx.strokeStyle = color;
    ctx.globalAlpha = 0.55;
    ctx.lineWidth = width;
    ctx.beginPath();
    ctx.moveTo(T.px(path[0][0]), T.py(path[0][1]));
    for (let k = 1; k < path.length; k++) ctx.lineTo(T.px(path[k][0]), T.py(path[k][1]));
    ctx.stroke();
    ctx.globalAlpha = 1;
  }

  // Every robot's plan, one stroke per colour (100 strokes of 300 points each were the page's
  // largest cost at 100 robots).
  function drawPaths(ctx, T, f, sel) {
    const byColor = {};
    for (const [i, path] of Object.entries(S.paths)) {
      if (+i === sel || !path || path.length < 2) continue;
      const r = f.robots[+i];
      const color = STATE_COLOR[r && r[3]] || "#999";
      (byColor[color] = byColor[color] || []).push(path);
    }
    ctx.globalAlpha = 0.55;
    ctx.lineWidth = 1;
    for (const [color, paths] of Object.entries(byColor)) {
      ctx.strokeStyle = color;
      ctx.beginPath();
      for (const path of paths) {
        ctx.moveTo(T.px(path[0][0]), T.py(path[0][1]));
        for (let k = 1; k < path.length; k++) ctx.lineTo(T.px(path[k][0]), T.py(path[k][1]));
      }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }

  // Robot i's outline (a mixed fleet's hello has every robot's own in `footprints`).
  function footprintPath(ctx, T, x, y, c, s, i) {
    const outline = (S.hello.footprints && S.hello.footprints[i]) || S.hello.footprint;
    outline.forEach(([fx, fy], k) => {
      const u = T.px(x + c * fx - s * fy), v = T.py(y + s * fx + c * fy);
      if (k === 0) ctx.moveTo(u, v); else ctx.lineTo(u, v);
    });
    ctx.closePath();
  }

  // Every robot: footprint filled in its state's colour and outlined, heading, a ring when it
  // holds, its name when `labels`: one fill per colour and one stroke per kind of line (about
  // 8 draw calls a frame instead of 300 at 100 robots); robots off the canvas are skipped. The
  // selected robot `sel` gets a white outline, stroked after the others.
  function drawRobots(ctx, T, f, sel, labels) {
    const names = S.hello.robots;
    const holding = new Set(f.holding);
    const byColor = {};
    const outline = new Path2D(), heading = new Path2D(), rings = new Path2D();
    const ring = Math.max(0.35 * T.scale, 7);
    const margin = 0.5 * T.scale + 20;  // [px] a robot this far outside the canvas is not drawn
    const w = ctx.canvas.width + margin, h = ctx.canvas.height + margin;
    let drawn = 0;
    const shown = [];  // [index, u, v] of the robots on the canvas
    f.robots.forEach((r, i) => {
      if (!r) return;
      drawn += 1;
      const [x, y, yaw, state] = r;
      const u = T.px(x), v = T.py(y);
      if (u < -margin || v < -margin || u > w || v > h) return;
      shown.push([i, u, v]);
      const c = Math.cos(yaw), s = Math.sin(yaw);
      const color = STATE_COLOR[state] || "#999";
      const fill = byColor[color] || (byColor[color] = new Path2D());
      footprintPath(fill, T, x, y, c, s, i);
      if (i !== sel) footprintPath(outline, T, x, y, c, s, i);
      heading.moveTo(u, v);
      heading.lineTo(T.px(x + 0.3 * c), T.py(y + 0.3 * s));
      if (holding.has(i)) {
        rings.moveTo(u + ring, v);
        rings.arc(u, v, ring, 0, 2 * Math.PI);
      }
    });
    for (const [color, path] of Object.entries(byColor)) {
      ctx.fillStyle = color;
      ctx.fill(path);
    }
    ctx.strokeStyle = "#111";
    ctx.lineWidth = 1;
    ctx.stroke(outline);
    const r = sel >= 0 ? f.robots[sel] : null;
    if (r) {
      const selected = new Path2D();
      footprintPath(selected, T, r[0], r[1], Math.cos(r[2]), Math.sin(r[2]), sel);
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 2;
      ctx.stroke(selected);
    }
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = Math.max(1, 0.03 * T.scale);
    ctx.stroke(heading);
    ctx.strokeStyle = "#ff8c00";
    ctx.lineWidth = 2;
    ctx.stroke(rings);
    if (labels) {
      ctx.font = `${Math.max(9, Math.min(13, 0.22 * T.scale))}px sans-serif`;
      for (const [i, u, v] of shown) label(ctx, names[i], u + 0.25 * T.scale + 2, v + 4);
    }
    return drawn;
  }

  // The scan in map: the outline of what the lidar sees (a beam without a return reaches
  // range_max) and the points it hit.
  function scanGeometry(scan) {
    const outline = [], hits = [];
    const [px, py, pyaw] = scan.pose;
    const [lx, ly, lyaw] = scan.lidar;
    const c = Math.cos(pyaw), s = Math.sin(pyaw);
    scan.ranges.forEach((r, k) => {
      const a = scan.angle_min + k * scan.angle_increment + lyaw;
      const d = r === null ? scan.range_max : r;
      const bx = lx + d * Math.cos(a), by = ly + d * Math.sin(a);
      const p = [px + c * bx - s * by, py + s * bx + c * by];
      outline.push(p);
      if (r !== null) hits.push(p);
    });
    return { outline, hits };
  }

  function drawScan(ctx, T, scan) {
    const { outline, hits } = scanGeometry(scan);
    S.scanPoints = hits.length;
    if (!outline.length) return;
    ctx.fillStyle = "rgba(255, 60, 60, 0.10)";
    ctx.strokeStyle = "rgba(255, 80, 80, 0.6)";
    ctx.lineWidth = 1;
    ctx.beginPath();
    outline.forEach(([x, y], k) => {
      if (k === 0) ctx.moveTo(T.px(x), T.py(y)); else ctx.lineTo(T.px(x), T.py(y));
    });
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
    const dots = new Path2D();
    for (const [x, y] of hits) dots.rect(T.px(x) - 1.5, T.py(y) - 1.5, 3, 3);
    ctx.fillStyle = "#ff3030";
    ctx.fill(dots);
  }

  function drawGoal(ctx, T, status) {
    if (!status || status.goal_x === undefined) return;
    const gx = +status.goal_x, gy = +status.goal_y, gyaw = +status.goal_yaw;
    ctx.strokeStyle = "#39e75f";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(T.px(gx), T.py(gy), Math.max(0.15 * T.scale, 5), 0, 2 * Math.PI);
    ctx.moveTo(T.px(gx), T.py(gy));
    ctx.lineTo(T.px(gx + 0.4 * Math.cos(gyaw)), T.py(gy + 0.4 * Math.sin(gyaw)));
    ctx.stroke();
  }

  function drawScene(canvas, T, opts) {
    const ctx = canvas.getContext("2d");
    if (!S.hello) return 0;
    drawBackground(canvas, ctx, T);
    const f = S.frame;
    if (!f) return 0;
    const sel = selectedIndex();
    if (opts.allPaths) drawPaths(ctx, T, f, sel);
    if (sel >= 0) drawPath(ctx, T, S.paths[sel], "#7fffd4", 2);
    const rs = sel >= 0 ? S.robot[sel] : null;
    if (rs && rs.scan) drawScan(ctx, T, rs.scan);
    if (rs && rs.status) drawGoal(ctx, T, rs.status);
    return drawRobots(ctx, T, f, sel, opts.labels);
  }

  function draw() {
    if (!S.hello) return;
    if (!ROBOT_PAGE) {
      if (!S.view) fitView();
      const T = transformFor(mapCanvas, S.view);
      // Names when they fit: up to 40 robots from 18 px/m, more once zoomed in (text is the
      // dearest thing to draw).
      const n = S.hello.robots.length;
      S.drawn = drawScene(mapCanvas, T, { allPaths: true, labels: T.scale > (n <= 40 ? 18 : 60) });
      setText($("kpi-robots"), S.frame ? `${S.drawn}/${S.hello.robots.length}` : "-");
    }
    const i = selectedIndex();
    if (i >= 0 && S.frame && S.frame.robots[i]) {
      const r = S.frame.robots[i];
      const T = transformFor(robotCanvas, { scale: S.zoom, cx: r[0], cy: r[1] });
      const drawn = drawScene(robotCanvas, T, { allPaths: false, labels: true });
      if (ROBOT_PAGE) {
        S.drawn = drawn;
        setText($("kpi-robots"), `${drawn}/${S.hello.robots.length}`);
      }
    }
  }

  // ------------------------------------------------------------------ interaction
  let drag = null;
  mapCanvas.addEventListener("mousedown", (ev) => { drag = { x: ev.offsetX, y: ev.offsetY, moved: false }; });
  mapCanvas.addEventListener("mousemove", (ev) => {
    if (!drag || !S.view) return;
    const dx = ev.offsetX - drag.x, dy = ev.offsetY - drag.y;
    if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
    if (drag.moved) {
      S.view.cx -= dx / S.view.scale;
      S.view.cy += dy / S.view.scale;
      S.userView = true;
      drag.x = ev.offsetX; drag.y = ev.offsetY;
      draw();
    }
  });
  mapCanvas.addEventListener("mouseup", (ev) => {
    const moved = drag && drag.moved;
    drag = null;
    if (moved || !S.frame || !S.view) return;
    const T = transformFor(mapCanvas, S.view);
    const [mx, my] = T.inv(ev.offsetX, ev.offsetY);
    let best = -1, bestD = Math.max(0.4, 10 / T.scale);
    S.frame.robots.forEach((r, i) => {
      if (!r) return;
      const d = Math.hypot(r[0] - mx, r[1] - my);
      if (d < bestD) { best = i; bestD = d; }
    });
    select(best >= 0 ? S.hello.robots[best] : null);
  });
  mapCanvas.addEventListener("wheel", (ev) => {
    if (!S.view) return;
    ev.preventDefault();
    const T = transformFor(mapCanvas, S.view);
    const [mx, my] = T.inv(ev.offsetX, ev.offsetY);
    const k = ev.deltaY < 0 ? 1.2 : 1 / 1.2;
    S.view.scale *= k;
    S.view.cx = mx - (mx - S.view.cx) / k;
    S.view.cy = my - (my - S.view.cy) / k;
    S.userView = true;
    draw();
  }, { passive: false });
  mapCanvas.addEventListener("dblclick", () => { S.userView = false; fitView(); draw(); });
  robotCanvas.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    S.zoom = Math.min(400, Math.max(10, S.zoom * (ev.deltaY < 0 ? 1.2 : 1 / 1.2)));
    draw();
  }, { passive: false });
  $("panel-close").addEventListener("click", () => select(null));
  window.addEventListener("resize", resize);

  // ------------------------------------------------------------------ for tests and probes
  window.dash = {
    stats: () => ({
      frames: S.frames,
      fps: fps(),
      robots: S.hello ? S.hello.robots.length : 0,
      drawn: S.drawn,
      kpi: S.frame ? S.frame.kpi : null,
      seq: S.frame ? S.frame.seq : null,
      selected: S.selected,
      scanPoints: S.scanPoints,
      status: selectedIndex() >= 0 && S.robot[selectedIndex()] ? S.robot[selectedIndex()].status : null,
      paths: Object.values(S.paths).filter((p) => p.length >= 2).length,
    }),
    select: (ns) => select(ns),
  };

  connect();
})();
