// dptpu viewer page: the live organized cloud over a WebSocket (/ws), drawn with three.js (bundled, r187).
// Messages (docs/viewer.md): binary = one cloud ("DPC1", uint32 n, n bytes of JSON, float32 xyz[count*3],
// float32 intensity[count]), text = one JSON record (type "status" for a ScanStatus, "config" on connect).
// Convention: points arrive in the camera optical frame (x right, y down, z forward, metres); three.js looks
// down -z with y up, so a point (x, y, z) is drawn at (x, -y, -z) and the scanner sits at the origin.
import { WebGLRenderer, Scene, PerspectiveCamera, BufferGeometry, BufferAttribute, Points, PointsMaterial, Color,
         Vector3, OrbitControls } from './three.bundle.min.js';

const BACKGROUND = 0x101418;
const SCANS_SHOWN = 8;
const state = { clouds: 0, statuses: 0, lastSequence: null, colourBy: 'depth', fitted: false, last: null };
window.viewerState = state;  // read by tests and handy in the console

const view = document.getElementById('view');
const renderer = new WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setSize(view.clientWidth, view.clientHeight);
view.appendChild(renderer.domElement);
const scene = new Scene();
scene.background = new Color(BACKGROUND);
const camera = new PerspectiveCamera(50, view.clientWidth / view.clientHeight, 0.005, 100);
const controls = new OrbitControls(camera, renderer.domElement);
controls.addEventListener('change', render);
const material = new PointsMaterial({ size: 2, sizeAttenuation: false, vertexColors: true });
let points = null;

function render() { renderer.render(scene, camera); }

window.addEventListener('resize', () => {
  camera.aspect = view.clientWidth / view.clientHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(view.clientWidth, view.clientHeight);
  render();
});

// Turbo colour map (Google's polynomial approximation, degree 5), t in [0, 1]: 0 blue (far) .. 1 red (near).
function poly(t, c) { return c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5])))); }
const TURBO_R = [0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943];
const TURBO_G = [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604];
const TURBO_B = [0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973];
function turbo(t, out, i) {
  t = Math.min(1, Math.max(0, t));
  out[i] = Math.min(1, Math.max(0, poly(t, TURBO_R)));
  out[i + 1] = Math.min(1, Math.max(0, poly(t, TURBO_G)));
  out[i + 2] = Math.min(1, Math.max(0, poly(t, TURBO_B)));
}

function colours(meta, xyz, intensity) {
  const n = meta.count, out = new Float32Array(3 * n);
  if (state.colourBy === 'intensity' && meta.intensity_range[1] > meta.intensity_range[0]) {
    const [lo, hi] = meta.intensity_range;
    for (let i = 0; i < n; i++) {
      const v = Number.isFinite(intensity[i]) ? 0.15 + 0.85 * (intensity[i] - lo) / (hi - lo) : 0.5;
      out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = v;
    }
  } else {
    const [lo, hi] = meta.z_range_m, span = hi > lo ? hi - lo : 1;
    for (let i = 0; i < n; i++) turbo(1 - (xyz[3 * i + 2] - lo) / span, out, 3 * i);
  }
  return out;
}

function showCloud(buffer) {
  const magic = new TextDecoder().decode(new Uint8Array(buffer, 0, 4));
  if (magic !== 'DPC1') return;
  const size = new DataView(buffer).getUint32(4, true);
  const meta = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, size)));
  const xyz = new Float32Array(buffer, 8 + size, 3 * meta.count);
  const intensity = new Float32Array(buffer, 8 + size + 12 * meta.count, meta.count);
  state.last = { meta, xyz, intensity };
  const position = new Float32Array(3 * meta.count);
  for (let i = 0; i < meta.count; i++) {
    position[3 * i] = xyz[3 * i]; position[3 * i + 1] = -xyz[3 * i + 1]; position[3 * i + 2] = -xyz[3 * i + 2];
  }
  const geometry = new BufferGeometry();
  geometry.setAttribute('position', new BufferAttribute(position, 3));
  geometry.setAttribute('color', new BufferAttribute(colours(meta, xyz, intensity), 3));
  if (points) { scene.remove(points); points.geometry.dispose(); }
  points = new Points(geometry, material);
  scene.add(points);
  if (!state.fitted && meta.count > 0) fit(geometry);
  state.clouds += 1;
  const [z0, z1] = meta.z_range_m;
  document.getElementById('cloud').textContent =
    `cloud ${state.clouds}: ${meta.count.toLocaleString('en')} points of ${meta.width}x${meta.height}` +
    `${meta.stride > 1 ? ` (every ${meta.stride}th)` : ''}, z ${z0.toFixed(3)}-${z1.toFixed(3)} m, ${meta.frame_id}`;
  render();
}

// Look at the cloud from the scanner's side: along the ray from the origin (the scanner) to its centre,
// far enough back that its bounding sphere fills about 80 % of the view.
function fit(geometry) {
  geometry.computeBoundingSphere();
  const sphere = geometry.boundingSphere, centre = sphere.center.clone();
  const towardScanner = centre.clone().negate().normalize();
  if (!Number.isFinite(towardScanner.x)) towardScanner.set(0, 0, 1);
  const distance = sphere.radius / Math.sin((camera.fov * Math.PI / 180) / 2) / 0.8;
  camera.position.copy(centre).addScaledVector(towardScanner, distance);
  camera.up.set(0, 1, 0);
  controls.target.copy(centre);
  camera.near = Math.max(distance / 1000, 1e-4); camera.far = distance * 10;
  camera.updateProjectionMatrix();
  controls.update();
  state.fitted = true;
}

function showStatus(record) {
  if (record.type === 'config') {
    state.colourBy = new URLSearchParams(location.search).get('color') || record.color_by;
    document.getElementById('colour').textContent = `colour: ${state.colourBy}`;
    return;
  }
  if (record.type !== 'status') return;
  state.statuses += 1;
  state.lastSequence = record.sequence_id;
  const line = document.createElement('div');
  line.className = record.level;
  const node = record.node.split('/').pop();
  line.textContent = `scan ${record.sequence_id} ${node}: ${record.state} ${record.level}` +
    (record.total_pixels ? `, ${record.valid_pixels.toLocaleString('en')} of ${record.total_pixels.toLocaleString('en')} px` : '') +
    `, ${record.duration_s.toFixed(3)} s` + (record.reason ? ` - ${record.reason}` : '');
  const scans = document.getElementById('scans');
  scans.prepend(line);
  while (scans.children.length > SCANS_SHOWN) scans.lastChild.remove();
}

document.getElementById('colour').addEventListener('click', () => {
  state.colourBy = state.colourBy === 'depth' ? 'intensity' : 'depth';
  document.getElementById('colour').textContent = `colour: ${state.colourBy}`;
  if (points && state.last) {
    points.geometry.setAttribute('color', new BufferAttribute(colours(state.last.meta, state.last.xyz, state.last.intensity), 3));
    render();
  }
});

function connect() {
  const socket = new WebSocket(`ws://${location.host}/ws`);
  socket.binaryType = 'arraybuffer';
  const connection = document.getElementById('connection');
  socket.onopen = () => { connection.textContent = '(live)'; };
  socket.onclose = () => { connection.textContent = '(reconnecting...)'; setTimeout(connect, 1000); };
  socket.onmessage = (event) => {
    if (typeof event.data === 'string') showStatus(JSON.parse(event.data));
    else showCloud(event.data);
  };
}

camera.position.set(0, 0, 0.001);
controls.target.set(0, 0, -1);
controls.update();
render();
connect();
