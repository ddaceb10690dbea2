// The 3D stage: renderer, lights, floor, the body and the draping garment.
//
// The garment's BufferGeometry is allocated once per try-on (vertex count from the init message): its
// position attribute uses DynamicDrawUsage and every frame is copied into `.array` in place, then
// normals and the bounding sphere are recomputed. Nothing is reallocated per frame.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { RoomEnvironment } from 'three/addons/environments/RoomEnvironment.js';
import { GLTFExporter } from 'three/addons/exporters/GLTFExporter.js';
import { strainColor } from './fitmap.js';

// The view is framed on the body again when its height changes by more than this fraction.
const REFRAME_HEIGHT_CHANGE = 0.06;

const GARMENT_COLORS = { top: 0xb5523b, bottom: 0x3f5f8a, dress: 0x7a4f7f };

function floorTexture() {
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 256;
  const g = canvas.getContext('2d');
  const gradient = g.createRadialGradient(128, 128, 8, 128, 128, 128);
  gradient.addColorStop(0, '#d9d1c6');
  gradient.addColorStop(0.35, '#e2dbd2');
  gradient.addColorStop(1, '#efebe6');
  g.fillStyle = gradient;
  g.fillRect(0, 0, 256, 256);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;
  return texture;
}

export class Stage {
  constructor(container) {
    this.container = container;
    const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    renderer.setSize(container.clientWidth, container.clientHeight);
    renderer.shadowMap.enabled = true;
    renderer.shadowMap.type = THREE.PCFSoftShadowMap;
    renderer.toneMapping = THREE.ACESFilmicToneMapping;
    renderer.toneMappingExposure = 1.0;
    container.appendChild(renderer.domElement);
    this.renderer = renderer;

    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xefebe6);
    scene.fog = new THREE.Fog(0xefebe6, 5, 11);
    const pmrem = new THREE.PMREMGenerator(renderer);
    scene.environment = pmrem.fromScene(new RoomEnvironment(), 0.04).texture;
    scene.environmentIntensity = 0.55;
    pmrem.dispose();
    this.scene = scene;

    const camera = new THREE.PerspectiveCamera(30, this.aspect(), 0.05, 60);
    camera.position.set(0.9, 1.25, 4.4);
    this.camera = camera;
    const controls = new OrbitControls(camera, renderer.domElement);
    controls.target.set(0, 0.95, 0);
    controls.enableDamping = true;
    controls.minDistance = 0.6;
    controls.maxDistance = 9;
    controls.maxPolarAngle = Math.PI * 0.495; // never under the floor
    controls.update();
    this.controls = controls;

    scene.add(new THREE.HemisphereLight(0xfff8f0, 0x8a7a6a, 0.9));
    const key = new THREE.DirectionalLight(0xfff3e6, 2.0);
    key.position.set(2.2, 4.5, 3.0);
    key.castShadow = true;
    key.shadow.mapSize.set(1024, 1024);
    key.shadow.camera.left = -1.4; key.shadow.camera.right = 1.4;
    key.shadow.camera.top = 2.4; key.shadow.camera.bottom = -0.6;
    key.shadow.camera.near = 1; key.shadow.camera.far = 12;
    key.shadow.bias = -0.0004;
    key.shadow.normalBias = 0.02;
    key.shadow.radius = 5;
    scene.add(key);
    const fill = new THREE.DirectionalLight(0xe8f0ff, 0.6);
    fill.position.set(-3, 2.5, 1.5);
    scene.add(fill);
    const rim = new THREE.DirectionalLight(0xffffff, 0.8);
    rim.position.set(-1, 3, -4);
    scene.add(rim);

    // A studio floor: a soft radial fade from a warm light grey into the background colour.
    const floor = new THREE.Mesh(
      new THREE.CircleGeometry(6, 96),
      new THREE.MeshStandardMaterial({ map: floorTexture(), roughness: 0.95, metalness: 0 }),
    );
    floor.rotation.x = -Math.PI / 2;
    floor.receiveShadow = true;
    scene.add(floor);

    this.skin = new THREE.MeshPhysicalMaterial({
      color: 0xd9a47f, roughness: 0.68, metalness: 0, sheen: 0.3, sheenColor: new THREE.Color(0xffd6c0),
      sheenRoughness: 0.7,
    });
    this.cloth = new THREE.MeshPhysicalMaterial({
      color: 0xb5523b, roughness: 0.85, metalness: 0, sheen: 1.0, sheenRoughness: 0.55,
      sheenColor: new THREE.Color(0xffffff), side: THREE.DoubleSide,
    });
    this.fitmapMaterial = new THREE.MeshStandardMaterial({
      color: 0xffffff, vertexColors: true, roughness: 0.8, metalness: 0, side: THREE.DoubleSide,
    });

    this.body = null;
    this.garment = null;
    this.strain = null;
    this.fitmapOn = false;
    this.framed = false;
    this.rightInset = 0;  // px of the stage covered on its right (the fit summary): setRightInset

    // Render on demand: only when something changed (a frame arrived, the camera moved, a toggle), so an
    // idle page costs nothing; the loop itself only checks a flag. Damped orbiting keeps it going.
    this.dirty = true;
    this.renders = 0;
    controls.addEventListener('change', () => this.requestRender());
    window.addEventListener('resize', () => this.resize());
    new ResizeObserver(() => this.resize()).observe(container);
    renderer.setAnimationLoop(() => {
      controls.update();
      if (!this.dirty) return;
      this.dirty = false;
      renderer.render(scene, camera);
      this.renders++;
    });
  }

  requestRender() { this.dirty = true; }

  aspect() { return Math.max(this.container.clientWidth, 1) / Math.max(this.container.clientHeight, 1); }

  resize() {
    this.camera.aspect = this.aspect();
    const w = Math.max(this.container.clientWidth, 1), h = Math.max(this.container.clientHeight, 1);
    // a card over the stage's right side: the view's centre moves left by half its width, so the body stands
    // in the middle of what is left (a raised right hand was under the fit summary at 1366 x 768)
    if (this.rightInset > 0 && this.rightInset < w / 2) this.camera.setViewOffset(w, h, this.rightInset / 2, 0, w, h);
    else this.camera.clearViewOffset();
    this.camera.updateProjectionMatrix();
    this.renderer.setSize(this.container.clientWidth, this.container.clientHeight);
    this.requestRender();
  }

  /** The width (px) of what covers the stage's right side, 0 for nothing. */
  setRightInset(px) {
    if (px === this.rightInset) return;
    this.rightInset = px;
    this.resize();
  }

  // ---- body -------------------------------------------------------------------------------
  /** Show a body mesh: vertices (n*3 floats, metres), faces (f*3 ints). */
  setBody(vertices, faces) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(vertices), 3));
    geometry.setIndex(new THREE.BufferAttribute(faces.length > 65535 * 3 ? new Uint32Array(faces) : new Uint32Array(faces), 1));
    geometry.computeVertexNormals();
    geometry.computeBoundingBox();
    geometry.computeBoundingSphere();
    if (this.body) {
      this.body.geometry.dispose();
      this.body.geometry = geometry;
    } else {
      this.body = new THREE.Mesh(geometry, this.skin);
      this.body.name = 'body';
      this.body.castShadow = true;
      this.body.receiveShadow = true;
      this.scene.add(this.body);
    }
    // framed once; again when the body grew or shrank much (a 210 cm body after a 170 cm one lost its head
    // above the view), from where the shopper turned the view to
    const height = geometry.boundingBox.max.y - geometry.boundingBox.min.y;
    if (!this.framed || Math.abs(height - this.framedHeight) > REFRAME_HEIGHT_CHANGE * this.framedHeight) {
      this.frame(geometry.boundingBox, this.framed);
      this.framed = true;
      this.framedHeight = height;
    }
    this.requestRender();
  }

  /** A re-posed body (same topology): its rest positions (n*3 floats, metres) and each vertex's part
   * (n ints); shown at once, then moved by `poseBody`. */
  setPosedBody(vertices, vertexPart) {
    this.bodyRest = new Float32Array(vertices);
    this.bodyPart = Int32Array.from(vertexPart);
    const position = this.body.geometry.getAttribute('position');
    position.setUsage(THREE.DynamicDrawUsage);
    this.poseBody(null);
  }

  /** Move the body's parts rigidly from its rest positions: `parts` (P rows of R (9, row-major) then t (3)),
   * or null for the rest pose itself. Writes into the allocated position attribute. */
  poseBody(parts) {
    if (!this.body || !this.bodyRest) return;
    const position = this.body.geometry.getAttribute('position');
    const out = position.array, rest = this.bodyRest, part = this.bodyPart;
    if (!parts) {
      out.set(rest);
    } else {
      for (let i = 0; i < part.length; i++) {
        const m = parts[part[i]];
        const x = rest[3 * i], y = rest[3 * i + 1], z = rest[3 * i + 2];
        out[3 * i] = m[0] * x + m[1] * y + m[2] * z + m[9];
        out[3 * i + 1] = m[3] * x + m[4] * y + m[5] * z + m[10];
        out[3 * i + 2] = m[6] * x + m[7] * y + m[8] * z + m[11];
      }
    }
    position.needsUpdate = true;
    this.body.geometry.computeVertexNormals();
    this.body.geometry.computeBoundingSphere();
    this.requestRender();
  }

  /** Point the camera at a box (the body), from the front and a little to the side (`keepDirection`: from
   * where it looks now). */
  frame(box, keepDirection = false) {
    const size = box.getSize(new THREE.Vector3());
    const center = box.getCenter(new THREE.Vector3());
    const fov = THREE.MathUtils.degToRad(this.camera.fov);
    const fitHeight = (size.y * 1.3) / (2 * Math.tan(fov / 2));
    const fitWidth = (Math.max(size.x, size.z) * 1.5) / (2 * Math.tan(fov / 2) * this.camera.aspect);
    const distance = Math.max(fitHeight, fitWidth, 1.0);
    const dir = keepDirection ? this.camera.position.clone().sub(this.controls.target).normalize()
      : new THREE.Vector3(0.28, 0.12, 1).normalize();
    this.controls.target.copy(center);
    this.camera.position.copy(center).addScaledVector(dir, distance);
    this.camera.near = distance / 50;
    this.camera.far = distance * 10;
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  // ---- garment ------------------------------------------------------------------------------
  /** A fresh garment geometry for `vertexCount` vertices and its faces (f*3 ints); allocated once. An outfit
   * gives `parts` (init.garments: each garment's category and `face_start` / `face_count`): each garment is
   * drawn in its own kind's colour, so a shirt over trousers does not look like one suit. */
  startGarment(vertexCount, faces, category, parts = null) {
    this.clearGarment();
    const geometry = new THREE.BufferGeometry();
    const position = new THREE.BufferAttribute(new Float32Array(vertexCount * 3), 3);
    position.setUsage(THREE.DynamicDrawUsage);
    geometry.setAttribute('position', position);
    const color = new THREE.BufferAttribute(new Float32Array(vertexCount * 3).fill(1), 3);
    geometry.setAttribute('color', color);
    geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(faces), 1));
    this.cloth.color.setHex(GARMENT_COLORS[category] ?? 0x8a6f5a);
    this.outfitCloths = null;
    if (parts?.length > 1) {
      this.outfitCloths = parts.map((part, i) => {
        geometry.addGroup(3 * part.face_start, 3 * part.face_count, i);
        const cloth = this.cloth.clone();
        cloth.color.setHex(GARMENT_COLORS[part.category] ?? 0x8a6f5a);
        return cloth;
      });
    }
    const mesh = new THREE.Mesh(geometry, this.fitmapOn && this.strain ? this.fitmapMaterial : this.clothOf());
    mesh.name = 'garment';
    mesh.castShadow = true;
    mesh.receiveShadow = true;
    mesh.visible = false; // until the first frame
    mesh.frustumCulled = false;
    this.scene.add(mesh);
    this.garment = mesh;
    this.strain = null;
    this.setFitMap(this.fitmapOn);
  }

  /** Copy one frame of positions (Float32Array, vertexCount*3) into the garment, in place. */
  updateGarment(positions) {
    if (!this.garment) return;
    const geometry = this.garment.geometry;
    const attribute = geometry.attributes.position;
    attribute.array.set(positions);
    attribute.needsUpdate = true;
    geometry.computeVertexNormals();
    geometry.computeBoundingSphere();
    this.garment.visible = true;
    this.requestRender();
  }

  clearGarment() {
    if (this.garment) {
      this.scene.remove(this.garment);
      this.garment.geometry.dispose();
      this.garment = null;
    }
    for (const cloth of this.outfitCloths ?? []) cloth.dispose();
    this.outfitCloths = null;
    this.strain = null;
    this.requestRender();
  }

  /** Per-vertex strain (ratio: 0.05 = 5 % stretch) for the fit map; `scaleMax` is the legend's top. */
  setStrain(strain, scaleMax) {
    if (!this.garment) return;
    this.strain = strain;
    const colors = this.garment.geometry.attributes.color;
    const c = new THREE.Color();
    for (let i = 0; i < strain.length; i++) {
      strainColor(strain[i] / scaleMax, c);
      colors.array[3 * i] = c.r; colors.array[3 * i + 1] = c.g; colors.array[3 * i + 2] = c.b;
    }
    colors.needsUpdate = true;
    this.setFitMap(this.fitmapOn);
  }

  setFitMap(on) {
    this.fitmapOn = on;
    if (this.garment) this.garment.material = on && this.strain ? this.fitmapMaterial : this.clothOf();
    this.requestRender();
  }

  /** The garment's cloth: one material, or an outfit's one per garment (drawn by the geometry's groups). */
  clothOf() { return this.outfitCloths ?? this.cloth; }

  /** The fitted garment as GLB bytes (ArrayBuffer), with fit-map colours as COLOR_0 when known. */
  async garmentGLB() {
    if (!this.garment) throw new Error('there is no fitted garment yet');
    const mesh = this.garment.clone();
    mesh.material = this.fitmapOn && this.strain ? this.fitmapMaterial : this.clothOf();
    const exporter = new GLTFExporter();
    return exporter.parseAsync(mesh, { binary: true });
  }

  /** Mean RGB of the canvas (0..255 per channel), for tests and sanity checks. */
  canvasSignature() {
    const gl = this.renderer.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    return px;
  }
}
