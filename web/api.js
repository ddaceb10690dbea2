// Talking to the service: REST (catalogue, body ranges, bodies) and the live try-on WebSocket.
//
// Every failure becomes an ApiError whose message is a sentence for the shopper.

export class ApiError extends Error {
  constructor(message, { status = 0, busy = false, stopped = false } = {}) {
    super(message);
    this.stopped = stopped;
    this.status = status;
    this.busy = busy;
  }
}

const FIELD_WORDS = {
  height: 'Height', chest: 'Chest', waist: 'Waist', hips: 'Hips', shoulder_width: 'Shoulder width',
  arm_length: 'Arm length', inseam: 'Inseam', neck: 'Neck', thigh: 'Thigh', upper_arm: 'Upper arm',
  arm_angle: 'Arm angle', elbow_bend: 'Elbow bend', leg_spread: 'Leg spread', garment_id: 'Garment',
};

/** A FastAPI/pydantic error body in words ("Chest: Input should be less than or equal to 150"). */
export function detailToWords(detail) {
  if (typeof detail === 'string') return detail;
  if (Array.isArray(detail)) {
    return detail.map((d) => {
      const loc = (d.loc || []).filter((x) => x !== 'body' && x !== 'query');
      const name = loc.length ? (FIELD_WORDS[loc[loc.length - 1]] || loc.join('.')) : 'Request';
      return `${name}: ${d.msg || 'invalid value'}`;
    }).join('; ');
  }
  if (detail && typeof detail === 'object') return detail.reason || detail.message || JSON.stringify(detail);
  return 'unexpected answer from the server';
}

async function failure(response) {
  let text = '';
  try {
    const body = await response.json();
    text = detailToWords(body.detail ?? body);
  } catch {
    text = response.statusText;
  }
  if (response.status === 503) {
    const after = response.headers.get('Retry-After');
    return new ApiError(`The fitting room is busy right now${after ? `; please try again in ${after} s` : ''}. ${text}`,
      { status: 503, busy: true });
  }
  return new ApiError(text || `request failed (${response.status})`, { status: response.status });
}

async function request(path, options = {}) {
  let response;
  try {
    response = await fetch(path, options);
  } catch {
    throw new ApiError('Cannot reach the server. Check your connection and try again.');
  }
  if (!response.ok) throw await failure(response);
  return response;
}

export async function getJSON(path) {
  return (await request(path)).json();
}

export async function postJSON(path, body) {
  return request(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
}

/** Flatten a JSON mesh ({vertices: [[x,y,z]...], faces: [[i,j,k]...]}) to typed arrays. */
export function flatMesh(mesh) {
  const v = mesh.vertices, f = mesh.faces;
  const vertices = new Float32Array(v.length * 3);
  for (let i = 0; i < v.length; i++) { vertices[3 * i] = v[i][0]; vertices[3 * i + 1] = v[i][1]; vertices[3 * i + 2] = v[i][2]; }
  const faces = new Uint32Array(f.length * 3);
  for (let i = 0; i < f.length; i++) { faces[3 * i] = f[i][0]; faces[3 * i + 1] = f[i][1]; faces[3 * i + 2] = f[i][2]; }
  return { vertices, faces };
}

const CLOSE_TRY_AGAIN_LATER = 1013;

/**
 * Run one live try-on over `WS /ws/tryon`.
 * handlers: onInit(init), onFrame(frameNo, step, positions Float32Array), onDone(done).
 * Resolves with the (first) done message; rejects with an ApiError. `session.cancel()` closes the socket.
 * A live request (`payload.live`) stays open after done: `session.sendPose(pose)` re-poses (a name or
 * angles), and then onBody(body message, its vertices a flat Float32Array, and vertex_part), onBodyPose(parts motions,
 * or null: the body in its own pose) and onFrame as it moves and settles, onPoseDone(done) at rest,
 * onLiveError(message) for a refused update, onClosed() when the connection ends.
 */
export function liveTryOn(payload, handlers) {
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  const ws = new WebSocket(`${scheme}://${location.host}/ws/tryon`);
  ws.binaryType = 'arraybuffer';
  let init = null;
  let decoded = null;  // reused for every uint16 frame
  let finished = false;
  let session = null;
  let body = null;  // a body message whose vertices (the next binary message) have not come yet
  const promise = new Promise((resolve, reject) => {
    let errorReason = null;
    ws.onopen = () => ws.send(JSON.stringify(payload));
    ws.onmessage = (event) => {
      if (typeof event.data === 'string') {
        const message = JSON.parse(event.data);
        if (message.type === 'init') {
          init = message;
          handlers.onInit?.(message);
        } else if (message.type === 'done') {
          if (finished) { handlers.onPoseDone?.(message); return; }
          finished = true;
          handlers.onDone?.(message);
          resolve(message);
        } else if (message.type === 'body') {
          body = message;
        } else if (message.type === 'body_pose') {
          handlers.onBodyPose?.(message.parts);
        } else if (message.type === 'error') {
          if (message.fatal === false) handlers.onLiveError?.(message);
          else errorReason = message.reason;
        }
        return;
      }
      if (!init) return;
      if (body) {  // the body message's vertices: float32 x, y, z, no header
        handlers.onBody?.({...body, vertices: new Float32Array(event.data)});
        body = null;
        return;
      }
      const enc = init.encoding;
      const header = new DataView(event.data, 0, enc.header_bytes);
      const frameNo = header.getUint32(0, true);
      const step = header.getUint32(4, true);
      const count = init.vertex_count * 3;
      let positions;
      if (enc.type === 'uint16') {  // position = origin + q * scale, per axis (metres)
        const q = new Uint16Array(event.data, enc.header_bytes, count);
        positions = decoded ??= new Float32Array(count);
        const [ox, oy, oz] = enc.origin;
        const [sx, sy, sz] = enc.scale;
        for (let i = 0; i < count; i += 3) {
          positions[i] = ox + q[i] * sx;
          positions[i + 1] = oy + q[i + 1] * sy;
          positions[i + 2] = oz + q[i + 2] * sz;
        }
      } else {
        positions = new Float32Array(event.data, enc.header_bytes, count);
      }
      handlers.onFrame?.(frameNo, step, positions);
    };
    ws.onerror = () => {};  // the close event carries what happened
    ws.onclose = (event) => {
      session.open = false;
      if (finished) { handlers.onClosed?.(); return; }
      if (session.cancelled) { reject(new ApiError('You stopped the try-on.', { stopped: true })); return; }
      if (event.code === CLOSE_TRY_AGAIN_LATER) {
        const wait = /try again in (\d+) s/.exec(errorReason || '');
        reject(new ApiError(`Every fitting room is busy right now. Please try again in ${wait ? `${wait[1]} seconds` : 'a few seconds'}.`,
          { busy: true }));
      } else if (errorReason) {
        reject(new ApiError(errorReason));
      } else {
        reject(new ApiError('The connection to the server was lost before the try-on finished.'));
      }
    };
  });
  session = { promise, cancelled: false, open: true, live: Boolean(payload.live) };
  session.cancel = () => { session.cancelled = true; ws.close(); };
  session.sendPose = (pose) => {
    if (ws.readyState !== WebSocket.OPEN) return false;
    ws.send(JSON.stringify({ type: 'pose', pose }));
    return true;
  };
  return session;
}

/** Save bytes as a file in the browser. */
export function saveBlob(data, filename, type = 'model/gltf-binary') {
  const blob = data instanceof Blob ? data : new Blob([data], { type });
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 2000);
}
