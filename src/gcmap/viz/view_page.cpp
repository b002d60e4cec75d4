#include "gcmap/viz/view_html.hpp"

namespace gcmap::viz {

// Placeholders: @THREE@ @ORBIT@ (the libraries), @META@ (JSON: bounds, colours, layers), @POINTS@
// (base64 of little-endian uint16 x y z per point, quantized within meta.min .. meta.max).
const char* const kViewPageTemplate = R"PAGE(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>gcmap view</title>
<style>
html, body { margin: 0; height: 100%; overflow: hidden; background: #14161a; font: 14px sans-serif; color: #eee; }
#panel { position: absolute; top: 10px; left: 10px; padding: 8px 12px; background: rgba(20,22,26,0.85); border-radius: 4px; }
#panel label { display: block; margin: 3px 0; cursor: pointer; }
#panel .swatch { display: inline-block; width: 14px; height: 4px; margin: 0 6px 3px 4px; }
#info { margin-top: 6px; color: #aaa; }
</style></head><body>
<div id="panel"><b>gcmap</b><div id="layers"></div><div id="info"></div>
<div style="color:#888">drag: rotate, right-drag: pan, wheel: zoom</div></div>
<script>@THREE@</script>
<script>@ORBIT@</script>
<script id="gcmap-meta" type="application/json">@META@</script>
<script id="gcmap-points" type="text/plain">@POINTS@</script>
<script>
(function () {
  'use strict';
  const meta = JSON.parse(document.getElementById('gcmap-meta').textContent);
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.setClearColor(0x14161a);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const lo = meta.min, hi = meta.max;
  const centre = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
  const extent = Math.max(hi[0] - lo[0], hi[1] - lo[1], 10);
  const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, extent / 1000, extent * 10);
  camera.up.set(0, 0, 1);  // z is up in gcmap's frames
  camera.position.set(centre.x, centre.y - 0.6 * extent, centre.z + 0.8 * extent);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.target.copy(centre);
  controls.update();

  function decodePoints() {
    const text = document.getElementById('gcmap-points').textContent.trim();
    const bin = atob(text), bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    const q = new DataView(bytes.buffer), n = Math.floor(bytes.length / 6);
    const pos = new Float32Array(3 * n), col = new Uint8Array(3 * n);
    const lut = meta.colormap, zlo = meta.height_range[0], zspan = meta.height_range[1] - meta.height_range[0];
    for (let i = 0; i < n; ++i) {
      for (let k = 0; k < 3; ++k) pos[3 * i + k] = lo[k] + q.getUint16(6 * i + 2 * k, true) * meta.step[k];
      const t = Math.min(255, Math.max(0, Math.round(255 * (pos[3 * i + 2] - zlo) / zspan)));
      col[3 * i] = lut[3 * t]; col[3 * i + 1] = lut[3 * t + 1]; col[3 * i + 2] = lut[3 * t + 2];
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('color', new THREE.BufferAttribute(col, 3, true));
    return { object: new THREE.Points(g, new THREE.PointsMaterial({ size: 2, sizeAttenuation: false, vertexColors: THREE.VertexColors })), count: n };
  }

  function segments(pairs, colour, opacity) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(pairs), 3));
    return new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: colour, transparent: opacity < 1, opacity: opacity }));
  }

  const layers = [];
  function addLayer(name, colour, object) {
    scene.add(object);
    layers.push(name);
    const label = document.createElement('label'), box = document.createElement('input');
    box.type = 'checkbox'; box.checked = true; box.id = 'layer-' + layers.length;
    box.addEventListener('change', function () { object.visible = box.checked; render(); });
    const swatch = document.createElement('span');
    swatch.className = 'swatch'; swatch.style.background = colour;
    label.appendChild(box); label.appendChild(swatch); label.appendChild(document.createTextNode(name));
    document.getElementById('layers').appendChild(label);
  }

  const map = decodePoints();
  addLayer('map (' + map.count + ' points)', '#7fb0d0', map.object);
  if (meta.trajectory.length >= 6) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(meta.trajectory), 3));
    addLayer('trajectory', meta.colours.trajectory, new THREE.Line(g, new THREE.LineBasicMaterial({ color: meta.colours.trajectory })));
  }
  if (meta.nodes.length) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(meta.nodes), 3));
    addLayer('submaps (' + meta.nodes.length / 3 + ')', meta.colours.node,
             new THREE.Points(g, new THREE.PointsMaterial({ size: 8, sizeAttenuation: false, color: meta.colours.node })));
  }
  for (const f of meta.factors) addLayer(f.label, f.colour, segments(f.segments, f.colour, f.opacity));

  function render() { renderer.render(scene, camera); }
  controls.addEventListener('change', render);
  window.addEventListener('resize', function () {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    render();
  });
  render();
  window.gcmapLoadedPoints = map.count;
  window.gcmapLayers = layers;
  document.getElementById('info').textContent = map.count + ' of ' + meta.map_points + ' map points loaded';
  document.title = 'gcmap view: ' + map.count + ' points';
  console.log('gcmap view: loaded ' + map.count + ' points');
})();
</script></body></html>
)PAGE";

}  // namespace gcmap::viz
