// The player of `host-sim ... --animate`: reads the run from the JSON in
// <script id="data"> (host-sim/src/output/animate: frames.rs gives the columns,
// scene.rs the geometry, both in SI units), draws the machine on #scene and the
// traces on #traces, and exposes `window.vibro` (docs/cli-run.md, "--animate").
// Vanilla JavaScript, nothing loaded, nothing logged.
(function () {
  "use strict";

  var D = JSON.parse(document.getElementById("data").textContent);
  var S = D.scene;
  var N = D.frames;

  // A column as numbers, `null` (not finite in the run) as NaN.
  function column(name) {
    var a = D.columns[name];
    if (!a) return null;
    var out = new Float64Array(a.length);
    for (var i = 0; i < a.length; i++) out[i] = a[i] === null ? NaN : a[i];
    return out;
  }

  var T = column("t");
  var T0 = T[0];
  var T1 = T[N - 1];
  var nBodies = S.bodies.length;
  // Each body's pose columns: the platform's `x, y, angle`, then `x_<name>`, ...
  var poseCols = S.bodies.map(function (b, i) {
    var suffix = i === 0 ? "" : "_" + b.name;
    return { x: column("x" + suffix), y: column("y" + suffix), a: column("angle" + suffix) };
  });
  var PHI = [column("phi1"), column("phi2")];
  var OMEGA = [column("omega1"), column("omega2")];
  var OFFSET = column("offset");
  var FN = S.contacts.map(function (c) { return column("fn_" + c.name); });
  var FT = S.contacts.map(function (c) { return column("ft_" + c.name); });
  var IMPACT_T = D.events.impacts.t;
  var IMPACT_C = D.events.impacts.contact;
  // The impact instants up to each impact: the run summary's count, which counts
  // the feet of one simultaneous impact once.
  var IMPACT_I = D.events.impacts.instant;
  // The impulses at each foot among the first q impact entries (one entry per
  // foot on its face at an impact, striking or not): FOOT_IMPACTS[c][q].
  var FOOT_IMPACTS = S.contacts.map(function (c, k) {
    var a = new Int32Array(IMPACT_T.length + 1);
    for (var q = 0; q < IMPACT_T.length; q++) a[q + 1] = a[q] + (IMPACT_C[q] === k ? 1 : 0);
    return a;
  });
  var CONTROLLER = D.events.controller;

  // The fundament's frame: `n` its normal, `u = (n_y, -n_x)` along it (+x on a
  // level floor), `P` a point of it. A point's `(s, h)`: along `u` and `n` from P.
  var P = S.fundament.point;
  var n = S.fundament.normal;
  var u = [n[1], -n[0]];
  function along(w) { return (w[0] - P[0]) * u[0] + (w[1] - P[1]) * u[1]; }
  function height(w) { return (w[0] - P[0]) * n[0] + (w[1] - P[1]) * n[1]; }
  function world(s, h) { return [P[0] + s * u[0] + h * n[0], P[1] + s * u[1] + h * n[1]]; }

  function finite(v, fallback) { return isFinite(v) ? v : fallback; }

  // The platform's `s` averaged over 0.2 s around each frame (less near the ends,
  // where the window shrinks to stay centred, so that a steady travel averages
  // to itself): the camera follows it, and the magnification acts about it (the
  // travel is not magnified).
  var SBAR = new Float64Array(N);
  (function () {
    var X = poseCols[0].x, Y = poseCols[0].y;
    var sum = new Float64Array(N + 1), last = 0;
    for (var i = 0; i < N; i++) {
      last = finite(along([X[i], Y[i]]), last);
      sum[i + 1] = sum[i] + last;
    }
    // The first frame at or after t.
    function from(t) {
      var lo = 0, hi = N;
      while (lo < hi) { var mid = (lo + hi) >> 1; if (T[mid] < t) lo = mid + 1; else hi = mid; }
      return lo;
    }
    for (var k = 0; k < N; k++) {
      var h = Math.min(0.1, T[k] - T0, T1 - T[k]);
      var a = Math.min(from(T[k] - h), k), b = Math.max(from(T[k] + h + 1e-12) - 1, k);
      SBAR[k] = (sum[b + 1] - sum[a]) / (b + 1 - a);
    }
  })();

  // Every body's pose at the first frame (the magnification's reference).
  var START = poseCols.map(function (c) {
    var w = [finite(c.x[0], 0), finite(c.y[0], 0)];
    return { s: along(w), h: height(w), a: finite(c.a[0], 0) };
  });

  // --- time -----------------------------------------------------------------

  var state = { t: T0, playing: false, rate: 0.05, mag: 1, span: 0 };

  // The frame `i` with T[i] <= t < T[i+1] (the last frame at the end).
  function frameAt(t) {
    var lo = 0, hi = N - 1;
    if (t >= T[hi]) return hi;
    while (hi - lo > 1) {
      var mid = (lo + hi) >> 1;
      if (T[mid] <= t) lo = mid; else hi = mid;
    }
    return lo;
  }

  // Linear interpolation of a column at t between frames `i` and `i + 1`.
  function lerp(a, i, f) {
    if (!a) return NaN;
    if (f <= 0 || i + 1 >= N) return a[i];
    return a[i] + (a[i + 1] - a[i]) * f;
  }

  // An eccentric angle at t: the wrapped step between two frames unwrapped by the
  // turns its mean rate makes in between.
  function phiAt(k, i, f) {
    var a = PHI[k];
    if (f <= 0 || i + 1 >= N) return a[i];
    var d = a[i + 1] - a[i];
    var w = 0.5 * (OMEGA[k][i] + OMEGA[k][i + 1]) * (T[i + 1] - T[i]);
    d += 2 * Math.PI * Math.round((w - d) / (2 * Math.PI));
    return a[i] + d * f;
  }

  // Everything drawn at t.
  function snapshot(t) {
    var i = frameAt(t);
    var f = i + 1 < N ? (t - T[i]) / (T[i + 1] - T[i]) : 0;
    if (!(f > 0)) f = 0;
    var bodies = poseCols.map(function (c) {
      return { x: lerp(c.x, i, f), y: lerp(c.y, i, f), a: lerp(c.a, i, f) };
    });
    // Forces jump at events: the frame's own, not interpolated.
    var j = f > 0.5 && i + 1 < N ? i + 1 : i;
    return {
      t: t, i: i, bodies: bodies,
      sbar: lerp(SBAR, i, f),
      phi: [phiAt(0, i, f), phiAt(1, i, f)],
      omega: [lerp(OMEGA[0], i, f), lerp(OMEGA[1], i, f)],
      offset: OFFSET ? OFFSET[j] : NaN,
      fn: FN.map(function (c) { return c[j]; }),
      ft: FT.map(function (c) { return c[j]; })
    };
  }

  // --- the scene ------------------------------------------------------------

  var scene = document.getElementById("scene");
  var sc = scene.getContext("2d");
  var W = scene.width, H = scene.height;

  // Pixels per metre: the bodies at t = 0 with a margin, at most 60 % of the width.
  var extent = (function () {
    var s0 = Infinity, s1 = -Infinity, h0 = 0, h1 = -Infinity;
    S.bodies.forEach(function (b, k) {
      var st = START[k], c = Math.cos(st.a), sn = Math.sin(st.a);
      b.outline.forEach(function (p) {
        var w = [finite(poseCols[k].x[0], 0) + c * p[0] - sn * p[1],
          finite(poseCols[k].y[0], 0) + sn * p[0] + c * p[1]];
        s0 = Math.min(s0, along(w)); s1 = Math.max(s1, along(w));
        h0 = Math.min(h0, height(w)); h1 = Math.max(h1, height(w));
      });
    });
    return { s0: s0, s1: s1, h0: h0, h1: h1 };
  })();
  // (At least 5 mm each way: a machine whose bodies are points or lines.)
  var scale = Math.min(0.6 * W / Math.max(extent.s1 - extent.s0, 0.005),
    0.55 * H / Math.max(extent.h1 - extent.h0, 0.005));
  var camS = 0.5 * (extent.s0 + extent.s1) - START[0].s;
  var camH = 0.5 * (extent.h0 + extent.h1);

  // The magnification acts on every point's displacement: a point of body k
  // whose true position is w(t) and whose reference is where it was at the first
  // frame, carried along the floor as far as the camera moved (D(t)), is drawn at
  // ref + M (w(t) - ref). For a rigid body (centre c, angle theta, a point p of
  // its centre-of-mass frame: w = c + R(theta) p) that is its centre drawn so, and
  // p mapped by R(theta_0) A with A = (1 - M) I + M R(theta - theta_0): a turn by
  // arg(A) and a scale |A|, the complex number 1 - M + M e^(i (theta - theta_0)).
  // So a foot that starts on the floor is drawn on the floor whenever it touches
  // it, and the shape stays a true shape, |A| times its size.
  function scaleTurn(d, M) {
    var re = 1 - M + M * Math.cos(d), im = M * Math.sin(d);
    return { k: Math.hypot(re, im), turn: Math.atan2(im, re) };
  }

  // Body k's drawn frame at snap: its centre (s, h), angle and scale.
  function shown(snap, k) {
    var b = snap.bodies[k], st = START[k], M = state.mag;
    var w = [b.x, b.y];
    var ref = snap.sbar + st.s - START[0].s;
    var A = scaleTurn(b.a - st.a, M);
    return {
      s: ref + M * (along(w) - ref),
      h: st.h + M * (height(w) - st.h),
      a: st.a + A.turn,
      k: A.k
    };
  }

  // Screen pixel of (s, h) in the fundament's frame, the camera at `cs`.
  function screenOf(s, h, cs) {
    var w = world(s, h), c = world(cs + camS, camH);
    return [W / 2 + (w[0] - c[0]) * scale, H / 2 - (w[1] - c[1]) * scale];
  }

  // A point p of a body (its centre-of-mass frame) drawn in the body's drawn
  // frame `pose` ([`shown`]), in the fundament's (s, h).
  function drawnPoint(pose, p) {
    var c = pose.k * Math.cos(pose.a), sn = pose.k * Math.sin(pose.a);
    var cw = world(pose.s, pose.h);
    var w = [cw[0] + c * p[0] - sn * p[1], cw[1] + sn * p[0] + c * p[1]];
    return [along(w), height(w)];
  }

  // The same point on screen.
  function bodyPoint(pose, p, cs) {
    var d = drawnPoint(pose, p);
    return screenOf(d[0], d[1], cs);
  }

  function arrow(ctx, from, dx, dy, colour, width) {
    var len = Math.hypot(dx, dy);
    if (!(len > 1)) return;
    var to = [from[0] + dx, from[1] + dy];
    var ux = dx / len, uy = dy / len, head = Math.min(10, 0.4 * len);
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(from[0], from[1]); ctx.lineTo(to[0], to[1]); ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(to[0], to[1]);
    ctx.lineTo(to[0] - head * ux - 0.5 * head * uy, to[1] - head * uy + 0.5 * head * ux);
    ctx.lineTo(to[0] - head * ux + 0.5 * head * uy, to[1] - head * uy - 0.5 * head * ux);
    ctx.closePath(); ctx.fill();
  }

  // A step of 1, 2 or 5 times a power of ten near `raw`.
  function niceStep(raw) {
    var m = Math.pow(10, Math.floor(Math.log10(raw))), f = raw / m;
    return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * m;
  }

  function fmt(v, d) { return isFinite(v) ? v.toFixed(d) : "-"; }

  var FORCE_PX = 70 / S.weight; // the machine's weight is 70 px

  function drawScene(snap) {
    var cs = snap.sbar, M = state.mag;
    sc.setTransform(1, 0, 0, 1, 0, 0);
    sc.fillStyle = "#fff"; sc.fillRect(0, 0, W, H);
    sc.lineJoin = "round";

    // The fundament: its line, shaded below, and ticks along it, at true floor
    // positions spread by the magnification about the camera, so that a foot
    // that sticks stays by its tick and one that slides passes the ticks at its
    // true distance. Magnified, a tick's position is no position of what stands
    // on it (the shapes keep their size): the ticks then carry no numbers, and a
    // legend gives their true spacing.
    var left = screenOf(cs + camS - W / scale, 0, cs), right = screenOf(cs + camS + W / scale, 0, cs);
    var down = [-n[0] * 2 * H, n[1] * 2 * H];
    sc.fillStyle = "#eee";
    sc.beginPath(); sc.moveTo(left[0], left[1]); sc.lineTo(right[0], right[1]);
    sc.lineTo(right[0] + down[0], right[1] + down[1]); sc.lineTo(left[0] + down[0], left[1] + down[1]);
    sc.closePath(); sc.fill();
    sc.strokeStyle = "#555"; sc.lineWidth = 1.5;
    sc.beginPath(); sc.moveTo(left[0], left[1]); sc.lineTo(right[0], right[1]); sc.stroke();
    var step = tickStep(M);
    var half = W / (scale * M);
    sc.font = "11px sans-serif"; sc.fillStyle = "#555"; sc.textAlign = "center";
    for (var k = Math.ceil((cs - half) / step); k * step <= cs + half; k++) {
      var s = k * step, p = screenOf(cs + M * (s - cs), 0, cs);
      sc.beginPath(); sc.moveTo(p[0], p[1]); sc.lineTo(p[0] - 8 * n[0] - 6 * u[0], p[1] + 8 * n[1] + 6 * u[1]); sc.stroke();
      if (M === 1) sc.fillText(fmt(s * 1e3, Math.max(0, -Math.floor(Math.log10(step * 1e3 + 1e-30)))) + " mm", p[0], p[1] + 16);
    }
    sc.textAlign = "left";
    sc.fillText(M === 1 ? "floor: position, mm (true scale)"
      : "floor ticks every " + (step * 1e3).toPrecision(3).replace(/\.?0+$/, "") + " mm of true floor, drawn " +
        M + " times as far apart (the motion's scale, not the shapes')", 10, H - 10);

    var poses = [];
    for (var b = 0; b < nBodies; b++) poses.push(shown(snap, b));

    // The bodies: outline (the convex hull the fundament check follows), centre
    // of mass, the name by the outline's upper left.
    S.bodies.forEach(function (body, k) {
      var pose = poses[k];
      var vertices = body.outline.map(function (p) { return bodyPoint(pose, p, cs); });
      sc.fillStyle = k === 0 ? "rgba(31,119,180,0.12)" : "rgba(148,103,189,0.12)";
      sc.strokeStyle = k === 0 ? "#1f77b4" : "#9467bd"; sc.lineWidth = 2;
      sc.beginPath(); sc.moveTo(vertices[0][0], vertices[0][1]);
      for (var c = 1; c < vertices.length; c++) sc.lineTo(vertices[c][0], vertices[c][1]);
      sc.closePath(); sc.fill(); sc.stroke();
      var cm = bodyPoint(pose, [0, 0], cs);
      sc.fillStyle = "#222"; sc.beginPath(); sc.arc(cm[0], cm[1], 3, 0, 2 * Math.PI); sc.fill();
      var corner = vertices.reduce(function (a, v) { return v[0] + v[1] < a[0] + a[1] ? v : a; });
      sc.font = "12px sans-serif"; sc.textAlign = "left";
      sc.fillText(body.name, corner[0] + 4, corner[1] + 14);
    });

    // The joints, a spring drawn as a coil around them.
    S.joints.forEach(function (j) {
      var p = bodyPoint(poses[j.body], j.point, cs);
      sc.strokeStyle = "#333"; sc.lineWidth = 1.5;
      sc.beginPath(); sc.arc(p[0], p[1], 4, 0, 2 * Math.PI); sc.stroke();
      if (j.spring) {
        sc.strokeStyle = "#8c564b"; sc.beginPath();
        for (var q = 0; q <= 40; q++) {
          var r = 6 + q * 0.25, a = q * 0.5;
          var px = p[0] + r * Math.cos(a), py = p[1] + r * Math.sin(a);
          if (q === 0) sc.moveTo(px, py); else sc.lineTo(px, py);
        }
        sc.stroke();
      }
      sc.fillStyle = "#333"; sc.font = "11px sans-serif"; sc.fillText(j.name, p[0] + 10, p[1] - 10);
    });

    // The rotors: axis, eccentric circle, the eccentric at its angle.
    S.rotors.forEach(function (r, k) {
      var pose = poses[r.body];
      var ax = bodyPoint(pose, r.axis, cs);
      var a = pose.a + snap.phi[k];
      var e = r.eccentricity, ke = pose.k * e;
      var ex = bodyPoint(pose, [r.axis[0] + e * Math.cos(snap.phi[k]), r.axis[1] + e * Math.sin(snap.phi[k])], cs);
      sc.strokeStyle = "#bbb"; sc.lineWidth = 1;
      sc.beginPath(); sc.arc(ax[0], ax[1], ke * scale, 0, 2 * Math.PI); sc.stroke();
      if (isFinite(a)) {
        sc.strokeStyle = "#ff7f0e"; sc.lineWidth = 3;
        sc.beginPath(); sc.moveTo(ax[0], ax[1]); sc.lineTo(ex[0], ex[1]); sc.stroke();
        sc.fillStyle = "#ff7f0e"; sc.beginPath(); sc.arc(ex[0], ex[1], Math.max(4, 0.25 * ke * scale), 0, 2 * Math.PI); sc.fill();
      }
      sc.fillStyle = "#222"; sc.beginPath(); sc.arc(ax[0], ax[1], 3, 0, 2 * Math.PI); sc.fill();
      sc.font = "11px sans-serif"; sc.textAlign = "center";
      sc.fillText(r.name + (r.sense > 0 ? " (ccw)" : " (cw)"), ax[0], ax[1] - ke * scale - 6);
    });

    // The contacts: the foot, its face, its friction cone while closed, the
    // contact force (fn along the face's normal, ft along t = (-n_y, n_x)).
    var hold = Math.max(0.004, 0.3 * state.rate);
    var recent = {};
    for (var q = firstImpactAfter(snap.t - hold); q < IMPACT_T.length && IMPACT_T[q] <= snap.t; q++) {
      recent[IMPACT_C[q]] = IMPACT_T[q];
    }
    S.contacts.forEach(function (c, k) {
      var foot = bodyPoint(poses[c.body], c.point, cs);
      var nn = c.normal;
      if (c.against >= 0) {
        var fp = poses[c.against], ca = Math.cos(fp.a), sa = Math.sin(fp.a);
        nn = [ca * c.normal[0] - sa * c.normal[1], sa * c.normal[0] + ca * c.normal[1]];
        var face = bodyPoint(fp, c.face, cs);
        sc.strokeStyle = "#555"; sc.lineWidth = 2;
        sc.beginPath(); sc.moveTo(face[0] - 12 * nn[1], face[1] - 12 * nn[0]);
        sc.lineTo(face[0] + 12 * nn[1], face[1] + 12 * nn[0]); sc.stroke();
      }
      var tt = [-nn[1], nn[0]];
      var fn = snap.fn[k], ft = snap.ft[k];
      if (fn > 0) {
        var mu = Math.atan(c.friction), len = 80;
        sc.strokeStyle = "#999"; sc.lineWidth = 1; sc.setLineDash([4, 3]);
        [-mu, mu].forEach(function (g) {
          var dx = Math.cos(g) * nn[0] - Math.sin(g) * nn[1], dy = Math.sin(g) * nn[0] + Math.cos(g) * nn[1];
          sc.beginPath(); sc.moveTo(foot[0], foot[1]); sc.lineTo(foot[0] + len * dx, foot[1] - len * dy); sc.stroke();
        });
        sc.setLineDash([]);
        var fx = (fn * nn[0] + ft * tt[0]) * FORCE_PX, fy = (fn * nn[1] + ft * tt[1]) * FORCE_PX;
        arrow(sc, foot, fx, -fy, "#d62728", 2.5);
      }
      sc.fillStyle = "#222"; sc.beginPath(); sc.arc(foot[0], foot[1], 3.5, 0, 2 * Math.PI); sc.fill();
      if (recent[k] !== undefined) {
        var age = (snap.t - recent[k]) / hold;
        sc.strokeStyle = "rgba(214,39,40," + (1 - age).toFixed(3) + ")"; sc.lineWidth = 3;
        sc.beginPath(); sc.arc(foot[0], foot[1], 8 + 14 * age, 0, 2 * Math.PI); sc.stroke();
      }
      sc.fillStyle = "#222"; sc.font = "12px sans-serif"; sc.textAlign = "left";
      sc.fillText(c.name, foot[0] + 7, foot[1] - 7);
    });

    // The numbers.
    sc.textAlign = "left"; sc.fillStyle = "#222"; sc.font = "14px sans-serif";
    var lines = ["t = " + fmt(snap.t, 4) + " s of " + fmt(T1, 3) + " s"];
    var speeds = S.rotors.map(function (r, k) {
      return r.name + " " + fmt(r.sense * snap.omega[k] * 30 / Math.PI, 0) + " rpm";
    });
    lines.push("rotor speeds (driven sense): " + speeds.join(", "));
    if (OFFSET) lines.push("phase offset: " + fmt(snap.offset, 1) + " deg");
    var st = controllerAt(snap.t);
    if (st) lines.push("controller: " + st);
    var im = impactsAt(snap.t);
    lines.push("impacts so far: " + im.instants + " (instants, as the summary counts); impulses: " +
      S.contacts.map(function (c, k) { return c.name + " " + im.feet[k]; }).join(", "));
    lines.forEach(function (l, k) { sc.fillText(l, 10, 20 + 18 * k); });
    sc.textAlign = "right";
    sc.font = "bold 15px sans-serif";
    sc.fillText("displacement \u00d7" + M, W - 10, 20);
    sc.font = "12px sans-serif";
    sc.fillText(M === 1 ? "true scale" : "every point's displacement magnified " + M + " times (not the travel)", W - 10, 38);
    if (M !== 1) sc.fillText(sizeNote(M), W - 10, 86);
    sc.fillText("playback " + rateText(state.rate) + " real time", W - 10, 54);
    sc.fillText("force arrows: weight = 70 px; dashed: friction cone", W - 10, 70);
    // A 20 mm bar of true size.
    var bar = 0.02 * scale;
    sc.strokeStyle = "#222"; sc.lineWidth = 2;
    sc.beginPath(); sc.moveTo(W - 10 - bar, H - 14); sc.lineTo(W - 10, H - 14); sc.stroke();
    sc.fillText("20 mm (shapes, true size)", W - 14 - bar, H - 10);
  }

  function rateText(r) { return r >= 1 ? String(r) : "1/" + Math.round(1 / r); }

  // The floor ticks' true spacing at magnification M, m: about 70 px apart drawn.
  function tickStep(M) { return niceStep(70 / (scale * M)); }

  // The impact instants (the summary's count) and the impulses at each foot up to t.
  function impactsAt(t) {
    var q = firstImpactAfter(t + 1e-12);
    return {
      instants: q > 0 ? IMPACT_I[q - 1] : 0,
      feet: FOOT_IMPACTS.map(function (a) { return a[q]; })
    };
  }

  // Index of the first impact after t.
  function firstImpactAfter(t) {
    var lo = 0, hi = IMPACT_T.length;
    while (lo < hi) {
      var mid = (lo + hi) >> 1;
      if (IMPACT_T[mid] < t) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  // The controller's state and latched fault at t, from its events.
  function controllerAt(t) {
    var s = "", fault = "";
    for (var k = 0; k < CONTROLLER.length && CONTROLLER[k][0] <= t; k++) {
      if (CONTROLLER[k][1] === "state") { s = CONTROLLER[k][2]; if (s !== "fault") fault = ""; }
      else fault = CONTROLLER[k][2];
    }
    return s + (fault ? " (" + fault + ")" : "");
  }

  // --- the traces -----------------------------------------------------------

  var traces = document.getElementById("traces");
  var tc = traces.getContext("2d");
  var TW = traces.width, TH = traces.height;
  var PL = 78, PR = 14, PT = 8, PB = 30;
  var COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"];

  function mapped(a, f) {
    var out = new Float64Array(N);
    for (var i = 0; i < N; i++) out[i] = f(a[i], i);
    return out;
  }

  var PANELS = [
    { title: "x, platform centre of mass", unit: "mm", series: [{ label: "x", data: mapped(poseCols[0].x, function (v) { return v * 1e3; }) }] },
    { title: "y - y(0), the hop", unit: "\u00b5m", series: [{ label: "y", data: mapped(poseCols[0].y, function (v) { return (v - poseCols[0].y[0]) * 1e6; }) }] },
    { title: "pitch angle", unit: "deg", series: [{ label: "angle", data: mapped(poseCols[0].a, function (v) { return v * 180 / Math.PI; }) }] },
    { title: "rotor speeds, driven sense", unit: "rpm", series: S.rotors.map(function (r, k) {
      return { label: r.name, data: mapped(OMEGA[k], function (v) { return r.sense * v * 30 / Math.PI; }) };
    }) }
  ];
  if (OFFSET) PANELS.push({ title: "phase offset", unit: "deg", series: [{ label: "offset", data: OFFSET }], fixed: [0, 360], wrap: 360 });
  PANELS.push({ title: "normal contact force (ticks: impulses at the feet)", unit: "N", series: S.contacts.map(function (c, k) {
    return { label: "fn_" + c.name, data: FN[k] };
  }), impacts: true });

  var panelH = (TH - PT - PB) / PANELS.length;

  // The visible span of the traces at t.
  function span(t) {
    if (!(state.span > 0)) return [T0, T1];
    var a = Math.max(T0, t - state.span / 2), b = Math.min(T1, a + state.span);
    return [Math.max(T0, b - state.span), b];
  }

  function drawPanel(p, top, t0, t1) {
    var h = panelH - 22, y0 = top + 18, w = TW - PL - PR;
    var i0 = Math.max(0, frameAt(t0)), i1 = Math.min(N - 1, frameAt(t1) + 1);
    var lo = Infinity, hi = -Infinity;
    if (p.fixed) { lo = p.fixed[0]; hi = p.fixed[1]; } else {
      p.series.forEach(function (s) {
        for (var i = i0; i <= i1; i++) { var v = s.data[i]; if (isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; } }
      });
      if (!(hi >= lo)) { lo = 0; hi = 1; }
      if (hi - lo < 1e-9 * Math.max(1, Math.abs(hi))) { lo -= 0.5; hi += 0.5; }
      var pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
    }
    var step = niceStep((hi - lo) / 3);
    tc.font = "11px sans-serif"; tc.fillStyle = "#222"; tc.textAlign = "right";
    tc.strokeStyle = "#e4e4e4"; tc.lineWidth = 1;
    for (var v = Math.ceil(lo / step) * step; v <= hi; v += step) {
      var py = y0 + h - (v - lo) / (hi - lo) * h;
      tc.beginPath(); tc.moveTo(PL, py); tc.lineTo(PL + w, py); tc.stroke();
      tc.fillText(String(+v.toPrecision(6)), PL - 6, py + 4);
    }
    tc.textAlign = "left"; tc.font = "bold 12px sans-serif";
    tc.fillText(p.title + ", " + p.unit, PL, top + 12);
    var lx = PL + tc.measureText(p.title + ", " + p.unit).width + 16;
    tc.font = "11px sans-serif";
    p.series.forEach(function (s, k) {
      tc.fillStyle = COLOURS[k]; tc.fillRect(lx, top + 5, 14, 3);
      tc.fillStyle = "#222"; tc.fillText(s.label, lx + 18, top + 12);
      lx += 30 + tc.measureText(s.label).width;
    });
    tc.strokeStyle = "#999"; tc.strokeRect(PL, y0, w, h);
    tc.save(); tc.beginPath(); tc.rect(PL, y0, w, h); tc.clip();
    // Each pixel column's first, lowest, highest and last value: peaks stay.
    p.series.forEach(function (s, k) {
      tc.strokeStyle = COLOURS[k]; tc.lineWidth = 1.2; tc.beginPath();
      var pen = false, col = -1, cmin = 0, cmax = 0, prev = NaN;
      for (var i = i0; i <= i1; i++) {
        var v = s.data[i];
        if (!isFinite(v)) { pen = false; continue; }
        if (p.wrap && isFinite(prev) && Math.abs(v - prev) > p.wrap / 2) pen = false;
        prev = v;
        var px = PL + (T[i] - t0) / (t1 - t0) * w, py = y0 + h - (v - lo) / (hi - lo) * h;
        var c = Math.floor(px);
        if (pen && c === col) {
          if (py < cmin) { cmin = py; tc.lineTo(px, py); }
          else if (py > cmax) { cmax = py; tc.lineTo(px, py); }
          continue;
        }
        if (pen) tc.lineTo(px, py); else tc.moveTo(px, py);
        pen = true; col = c; cmin = cmax = py;
      }
      tc.stroke();
    });
    if (p.impacts && t1 - t0 <= 2) {
      tc.strokeStyle = "#d62728"; tc.lineWidth = 1;
      for (var q = firstImpactAfter(t0); q < IMPACT_T.length && IMPACT_T[q] <= t1; q++) {
        var ix = PL + (IMPACT_T[q] - t0) / (t1 - t0) * w;
        tc.beginPath(); tc.moveTo(ix, y0 + h); tc.lineTo(ix, y0 + h - 8); tc.stroke();
      }
    }
    tc.restore();
  }

  // The panels of [t0, t1] on a canvas of their own, redrawn when the span moves.
  var cache = document.createElement("canvas");
  cache.width = TW; cache.height = TH;
  var cached = null;
  function drawTraces(t) {
    var sp = span(t);
    if (!cached || cached[0] !== sp[0] || cached[1] !== sp[1]) {
      var keep = tc;
      tc = cache.getContext("2d");
      tc.fillStyle = "#fff"; tc.fillRect(0, 0, TW, TH);
      PANELS.forEach(function (p, k) { drawPanel(p, PT + k * panelH, sp[0], sp[1]); });
      var step = niceStep((sp[1] - sp[0]) / 8), w = TW - PL - PR;
      tc.fillStyle = "#222"; tc.textAlign = "center"; tc.font = "11px sans-serif";
      for (var v = Math.ceil(sp[0] / step) * step; v <= sp[1] + 1e-12; v += step) {
        tc.fillText(String(+v.toPrecision(6)), PL + (v - sp[0]) / (sp[1] - sp[0]) * w, TH - PB + 14);
      }
      tc.fillText("time, s", PL + w / 2, TH - 4);
      tc = keep;
      cached = sp;
    }
    tc.drawImage(cache, 0, 0);
    var x = PL + (t - sp[0]) / (sp[1] - sp[0]) * (TW - PL - PR);
    tc.strokeStyle = "#d62728"; tc.lineWidth = 1.5;
    tc.beginPath(); tc.moveTo(x, PT); tc.lineTo(x, TH - PB); tc.stroke();
  }

  // --- controls -------------------------------------------------------------

  var playButton = document.getElementById("play");
  var slider = document.getElementById("time");
  var clock = document.getElementById("clock");
  var rateSelect = document.getElementById("rate");
  var magSelect = document.getElementById("mag");
  var spanSelect = document.getElementById("span");
  slider.min = String(T0); slider.max = String(T1);

  // Each listed magnification's largest change of a drawn shape's size over the
  // run, |(|A| - 1)| ([`shown`]): the turn of a body, magnified, draws it larger.
  // One that would draw a body more than MAX_SIZE_ERROR off its size does not
  // show the true shape and is not offered (its entry says why).
  var MAX_SIZE_ERROR = 0.05;
  var MAGS = Array.prototype.map.call(magSelect.options, function (o) {
    var m = Number(o.value), err = 0;
    poseCols.forEach(function (c, k) {
      for (var i = 0; i < N; i++) {
        var e = Math.abs(scaleTurn(c.a[i] - START[k].a, m).k - 1);
        if (isFinite(e) && e > err) err = e;
      }
    });
    var offered = err <= MAX_SIZE_ERROR;
    if (!offered) {
      o.disabled = true;
      o.textContent += " (" + (100 * err).toFixed(0) + " % off)";
      o.title = "not offered: it would draw a shape " + (100 * err).toFixed(0) + " % off its true size";
    }
    return { mag: m, offered: offered, size_error: err };
  });
  function sizeNote(m) {
    var g = MAGS.filter(function (x) { return x.mag === m; })[0];
    return "shapes drawn within " + (100 * g.size_error).toFixed(1) + " % of their true size (turns magnified)";
  }

  // The largest offered magnification that keeps the platform's largest
  // displacement from its start (the hop, the pitch at its ends; not the travel)
  // within a quarter of its height.
  (function () {
    var outline = S.bodies[0].outline, reach = 0, low = Infinity, high = -Infinity;
    outline.forEach(function (p) {
      reach = Math.max(reach, Math.abs(p[0])); low = Math.min(low, p[1]); high = Math.max(high, p[1]);
    });
    var size = high - low;
    var c = poseCols[0], dev = 0;
    for (var i = 0; i < N; i++) {
      var d = Math.abs(height([c.x[i], c.y[i]]) - START[0].h) + Math.abs(c.a[i] - START[0].a) * reach;
      if (isFinite(d) && d > dev) dev = d;
    }
    var best = 1;
    MAGS.forEach(function (g) {
      if (g.offered && g.mag * dev <= 0.25 * size) best = Math.max(best, g.mag);
    });
    state.mag = best;
    magSelect.value = String(best);
  })();

  var lastDrawn = null;
  function draw() {
    var snap = snapshot(state.t);
    lastDrawn = snap;
    drawScene(snap);
    drawTraces(state.t);
    slider.value = String(state.t);
    clock.textContent = "t = " + state.t.toFixed(4) + " s";
    playButton.textContent = state.playing ? "pause" : "play";
  }

  function seek(t) {
    t = Number(t);
    if (!isFinite(t)) return;
    state.t = Math.min(T1, Math.max(T0, t));
    draw();
  }

  var wall = null;
  function tick(now) {
    if (!state.playing) { wall = null; return; }
    if (wall !== null) {
      state.t += (now - wall) / 1000 * state.rate;
      if (state.t >= T1) { state.t = T1; state.playing = false; }
    }
    wall = now;
    draw();
    if (state.playing) requestAnimationFrame(tick); else wall = null;
  }

  function play() {
    if (state.playing) return;
    if (state.t >= T1) state.t = T0;
    state.playing = true;
    wall = null;
    draw();
    requestAnimationFrame(tick);
  }

  function pause() {
    state.playing = false;
    draw();
  }

  playButton.addEventListener("click", function () { if (state.playing) pause(); else play(); });
  slider.addEventListener("input", function () { seek(slider.value); });
  rateSelect.addEventListener("change", function () { state.rate = Number(rateSelect.value); draw(); });
  magSelect.addEventListener("change", function () { state.mag = Number(magSelect.value); draw(); });
  spanSelect.addEventListener("change", function () { state.span = Number(spanSelect.value); cached = null; draw(); });
  traces.addEventListener("click", function (ev) {
    var r = traces.getBoundingClientRect(), x = (ev.clientX - r.left) * TW / r.width;
    var sp = span(state.t);
    if (x >= PL && x <= TW - PR) seek(sp[0] + (x - PL) / (TW - PL - PR) * (sp[1] - sp[0]));
  });
  document.addEventListener("keydown", function (ev) {
    if (ev.key === " " && ev.target === document.body) { ev.preventDefault(); if (state.playing) pause(); else play(); }
  });

  // Settings in the address's fragment: #t=1.25&mag=100&rate=0.01&span=0.1.
  (function () {
    var pick = function (select, v) {
      Array.prototype.forEach.call(select.options, function (o) {
        if (Number(o.value) === Number(v) && !o.disabled) select.value = o.value;
      });
      return Number(select.value);
    };
    location.hash.replace(/^#/, "").split("&").forEach(function (kv) {
      var p = kv.split("="), v = Number(p[1]);
      if (p.length !== 2 || !isFinite(v)) return;
      if (p[0] === "t") state.t = Math.min(T1, Math.max(T0, v));
      if (p[0] === "mag") state.mag = pick(magSelect, v);
      if (p[0] === "rate") state.rate = pick(rateSelect, v);
      if (p[0] === "span") state.span = pick(spanSelect, v);
    });
    state.rate = Number(rateSelect.value);
  })();

  var all = impactsAt(T1);
  document.getElementById("note").textContent = S.outline_note + ". " + N + " frames, one every " +
    (D.frame_step * 1e3) + " ms of simulated time (interpolated in between); " + all.instants +
    " impacts (instants, as the run's summary counts them); " + IMPACT_T.length +
    " impulses at the feet (" + S.contacts.map(function (c, k) {
      return c.name + " " + all.feet[k];
    }).join(", ") + ": every foot on its face at an impact takes one, striking or not; each is a red " +
    "ring and a tick on the force trace). Magnified, every point's displacement is multiplied (the travel along the floor " +
    "is not): a foot that starts on the floor is drawn on it whenever it touches it, and a body's magnified " +
    "turn draws it larger; a magnification that would draw a shape more than " + (100 * MAX_SIZE_ERROR) +
    " % off its size is not offered. Space or the button plays and pauses; a click on the traces moves the time there.";

  draw();

  // The page's interface for scripts (a browser test): read-only.
  window.vibro = Object.freeze({
    duration: T1,
    frames: N,
    t: function () { return state.t; },
    playing: function () { return state.playing; },
    play: play,
    pause: pause,
    seek: seek,
    magnification: function () { return state.mag; },
    rate: function () { return state.rate; },
    pose: function () {
      var b = lastDrawn.bodies[0];
      return { x: b.x, y: b.y, angle: b.a };
    },
    impacts: function () {
      var im = impactsAt(state.t), impulses = {};
      S.contacts.forEach(function (c, k) { impulses[c.name] = im.feet[k]; });
      return { instants: im.instants, impulses: impulses };
    },
    outlines: function () {
      return S.bodies.map(function (body, k) {
        var pose = shown(lastDrawn, k);
        return body.outline.map(function (p) {
          var d = drawnPoint(pose, p);
          return { s: d[0], h: d[1] };
        });
      });
    },
    feet: function () {
      return S.contacts.map(function (c) {
        var d = drawnPoint(shown(lastDrawn, c.body), c.point);
        return { name: c.name, s: d[0], h: d[1] };
      });
    },
    magnifications: function () {
      return MAGS.map(function (g) { return { mag: g.mag, offered: g.offered, size_error: g.size_error }; });
    },
    ticks: function () {
      var M = state.mag, step = tickStep(M);
      return { step: step, apart: M * step, numbered: M === 1 };
    }
  });
})();
