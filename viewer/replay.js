// singplan replay page: meshcat's scene plus a legend, a segment list that jumps the timeline,
// labels at the crossings and a joint-speed strip synced to the time cursor.
// Reads the global SINGPLAN (written by singplan/outputs/viewer.py); needs nothing but meshcat's bundle.
"use strict";
(function () {
  const data = SINGPLAN;
  const THREE = MeshCat.THREE;
  const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  for (const b64 of data.commands) {
    viewer.handle_command_bytearray(Uint8Array.from(atob(b64), (c) => c.charCodeAt(0)));
  }
  const animator = viewer.animator;
  // scheduled but stopped: the actions then follow seek() before the first "play"
  animator.play();
  animator.pause();

  const hex = (colour) => "#" + colour.toString(16).padStart(6, "0");
  const palette = data.palette;  // the report's colours, from singplan/outputs/timeline.py and svgplot.py
  const toThree = (xyz) => viewer.scene.localToWorld(new THREE.Vector3(xyz[0], xyz[1], xyz[2]));

  function currentTime() {
    return animator.actions.length ? animator.actions[0].time : 0;
  }

  function seek(t) {
    const time = Math.max(0, Math.min(data.duration, t));
    animator.pause();
    animator.seek(time);
    animator.display_progress(time);
  }

  function frameCamera() {
    // meshcat's scene is z-up inside a rotated three.js world: convert through the scene node
    const f = data.frame;
    const eye = f.center.map((c, i) => c + f.distance * f.direction[i]);
    const camera = viewer.camera;
    camera.position.copy(camera.parent.worldToLocal(toThree(eye)));
    viewer.controls.target.copy(camera.parent.worldToLocal(toThree(f.center)));
    viewer.controls.update();
    viewer.set_dirty();
  }

  function buildLegend() {
    const legend = document.getElementById("sp-legend");
    for (const [kind, colour] of Object.entries(data.colours)) {
      const item = document.createElement("span");
      item.innerHTML = `<i style="background:${hex(colour)}"></i>${kind}`;
      legend.appendChild(item);
    }
  }

  function buildSegments() {
    const list = document.getElementById("sp-segments");
    return data.segments.map((seg) => {
      const item = document.createElement("li");
      item.style.borderLeftColor = hex(seg.colour);
      item.innerHTML = `<b>${seg.title}</b><span class="sp-detail">${seg.detail}</span>`;
      item.addEventListener("click", () => seek(seg.t_jump));
      list.appendChild(item);
      return item;
    });
  }

  function buildLabels() {
    const layer = document.getElementById("sp-labels");
    return data.labels.map((label) => {
      const div = document.createElement("div");
      div.className = "sp-label";
      div.style.background = hex(palette.label);
      div.textContent = label.text;
      layer.appendChild(div);
      return { div, point: label.xyz };
    });
  }

  function placeLabels(labels) {
    const pane = document.getElementById("meshcat-pane");
    viewer.camera.updateMatrixWorld();
    for (const { div, point } of labels) {
      const p = toThree(point).project(viewer.camera);
      const visible = p.z < 1;
      div.style.display = visible ? "block" : "none";
      div.style.left = `${((p.x + 1) / 2) * pane.clientWidth}px`;
      div.style.top = `${((1 - p.y) / 2) * pane.clientHeight}px`;
    }
  }

  function drawStrip(canvas, time) {
    const width = (canvas.width = canvas.clientWidth);
    const height = (canvas.height = canvas.clientHeight);
    const ctx = canvas.getContext("2d");
    const s = data.speed;
    const top = Math.max(1.1, ...s.ratio) * 1.05;
    const x = (t) => (t / data.duration) * width;
    const y = (r) => height - 14 - (r / top) * (height - 20);
    for (const band of data.bands) {  // stretch kinds (segments, null-space pauses) as a band under the curve
      ctx.fillStyle = hex(band.colour);
      ctx.fillRect(x(band.t0), height - 8, Math.max(1, x(band.t1) - x(band.t0)), 8);
      if (band.kind in palette.shaded) {  // also shaded above the band
        ctx.globalAlpha = palette.shaded[band.kind];
        ctx.fillRect(x(band.t0), 0, x(band.t1) - x(band.t0), height - 8);
        ctx.globalAlpha = 1;
      }
    }
    ctx.strokeStyle = palette.limit;
    ctx.setLineDash([5, 4]);
    ctx.beginPath();
    ctx.moveTo(0, y(1));
    ctx.lineTo(width, y(1));
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.strokeStyle = palette.curve;
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    s.t.forEach((t, i) => (i ? ctx.lineTo(x(t), y(s.ratio[i])) : ctx.moveTo(x(t), y(s.ratio[i]))));
    ctx.stroke();
    ctx.fillStyle = "#333";
    ctx.fillText("max joint speed / limit", 6, height - 12);
    ctx.fillText("limit", width - 34, y(1) - 3);
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(x(time), 0);
    ctx.lineTo(x(time), height);
    ctx.stroke();
  }

  frameCamera();
  buildLegend();
  const items = buildSegments();
  const labels = buildLabels();
  const strip = document.getElementById("sp-speed");
  strip.parentElement.addEventListener("click", (event) => {
    seek((event.offsetX / strip.clientWidth) * data.duration);
  });
  seek(0);

  function tick() {
    const time = currentTime();
    drawStrip(strip, time);
    placeLabels(labels);
    data.segments.forEach((seg, i) => items[i].classList.toggle("sp-current", seg.t0 <= time && time <= seg.t1));
    requestAnimationFrame(tick);
  }
  tick();

  // for tests and for users' own scripts
  window.singplan = { viewer, seek, time: currentTime, segments: data.segments, ready: true };
})();
