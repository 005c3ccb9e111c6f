// geotrajd's JSON HTTP API (the proto3 JSON mapping of geotraj.v1; absent fields are zero,
// false, "" or []): one function per route, the bearer token from sessionStorage on every
// call, and errors as ApiError values carrying the google.rpc.Status the server sent.

const TOKEN_KEY = 'geotraj.token';

export function token() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || '';
  } catch {
    return '';
  }
}

export function setToken(value) {
  try {
    if (value) sessionStorage.setItem(TOKEN_KEY, value);
    else sessionStorage.removeItem(TOKEN_KEY);
  } catch {
    // sessionStorage refused (a sandboxed frame): the token lives as long as this call only.
  }
}

// gRPC status codes by number, for messages.
const CODE_NAMES = [
  'OK', 'CANCELLED', 'UNKNOWN', 'INVALID_ARGUMENT', 'DEADLINE_EXCEEDED', 'NOT_FOUND',
  'ALREADY_EXISTS', 'PERMISSION_DENIED', 'RESOURCE_EXHAUSTED', 'FAILED_PRECONDITION', 'ABORTED',
  'OUT_OF_RANGE', 'UNIMPLEMENTED', 'INTERNAL', 'UNAVAILABLE', 'DATA_LOSS', 'UNAUTHENTICATED',
];

export function codeName(code) {
  return CODE_NAMES[code] || `code ${code}`;
}

// A refused call: HTTP status, the google.rpc.Status fields, and the field violations of a
// google.rpc.BadRequest (and the violations of a google.rpc.PreconditionFailure) flattened
// to {field, description}.
export class ApiError extends Error {
  constructor(httpStatus, status) {
    const code = typeof status.code === 'number' ? status.code : 2;
    super(status.message || `HTTP ${httpStatus}`);
    this.name = 'ApiError';
    this.httpStatus = httpStatus;
    this.code = code;
    this.fieldViolations = [];
    this.preconditionViolations = [];
    for (const detail of status.details || []) {
      const type = detail['@type'] || '';
      if (type.endsWith('google.rpc.BadRequest')) {
        for (const v of detail.fieldViolations || []) {
          this.fieldViolations.push({ field: v.field || '', description: v.description || '' });
        }
      } else if (type.endsWith('google.rpc.PreconditionFailure')) {
        for (const v of detail.violations || []) {
          this.preconditionViolations.push({ type: v.type || '', subject: v.subject || '',
            description: v.description || '' });
        }
      }
    }
  }

  get summary() {
    if (this.httpStatus === 401 || this.code === 16) return `UNAUTHENTICATED: ${this.message} (set the token)`;
    if (this.httpStatus === 403 || this.code === 7) return `PERMISSION_DENIED: ${this.message}`;
    return `${codeName(this.code)}: ${this.message}`;
  }
}

function headers(json) {
  const h = {};
  if (json) h['Content-Type'] = 'application/json';
  const t = token();
  if (t) h.Authorization = `Bearer ${t}`;
  return h;
}

async function errorOf(response) {
  const text = await response.text();
  let status;
  try {
    status = JSON.parse(text);
  } catch {
    status = { code: response.status === 401 ? 16 : response.status === 403 ? 7 : 2,
      message: text.trim() || response.statusText };
  }
  if (typeof status !== 'object' || status === null) status = { message: String(status) };
  return new ApiError(response.status, status);
}

async function call(method, route, body, signal) {
  let response;
  try {
    response = await fetch(route, {
      method,
      headers: headers(body !== undefined),
      body: body !== undefined ? JSON.stringify(body) : undefined,
      signal,
    });
  } catch (e) {
    if (e.name === 'AbortError') throw e;
    throw new ApiError(0, { code: 14, message: `geotrajd unreachable: ${e.message}` });
  }
  if (!response.ok) throw await errorOf(response);
  return response.json();
}

export const plan = (request, signal) => call('POST', 'v1/plan', request, signal);
export const analyze = (request, signal) => call('POST', 'v1/analyze', request, signal);
export const convert = (request, signal) => call('POST', 'v1/convert', request, signal);
export const forwardKinematics = (request, signal) => call('POST', 'v1/fk', request, signal);
export const inverseKinematics = (request, signal) => call('POST', 'v1/ik', request, signal);
export const robots = (signal) => call('GET', 'v1/robots', undefined, signal);

// POST /v1/stream: newline-delimited JSON, one SampleBatch a line; a failure after the first
// line ends the body with {"error": google.rpc.Status}. Calls onBatch(batch) per line and
// resolves with the number of samples.
export async function stream(request, onBatch, signal) {
  let response;
  try {
    response = await fetch('v1/stream', { method: 'POST', headers: headers(true),
      body: JSON.stringify(request), signal });
  } catch (e) {
    if (e.name === 'AbortError') throw e;
    throw new ApiError(0, { code: 14, message: `geotrajd unreachable: ${e.message}` });
  }
  if (!response.ok) throw await errorOf(response);
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffer = '';
  let count = 0;
  const line = (text) => {
    if (!text.trim()) return;
    const value = JSON.parse(text);
    if (value.error) throw new ApiError(response.status, value.error);
    count += (value.samples || []).length;
    onBatch(value);
  };
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    buffer += decoder.decode(value, { stream: true });
    let end;
    while ((end = buffer.indexOf('\n')) >= 0) {
      line(buffer.slice(0, end));
      buffer = buffer.slice(end + 1);
    }
  }
  buffer += decoder.decode();
  line(buffer);
  return count;
}

// Runs fn over items with at most `limit` calls in flight; results in the items' order.
export async function mapLimited(items, limit, fn) {
  const results = new Array(items.length);
  let next = 0;
  const worker = async () => {
    while (next < items.length) {
      const i = next++;
      results[i] = await fn(items[i], i);
    }
  };
  await Promise.all(Array.from({ length: Math.min(limit, items.length) }, worker));
  return results;
}
