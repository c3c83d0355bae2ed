// Screen passes: the float scene target and the reference accumulation target, the accumulation of
// one pass into the latter, and the display pass (premultiplied RGBA over the background, clamped,
// exact sRGB OETF, optional split-screen divider) into the canvas.

import { compileProgram, createRenderTarget } from './gl-resources.js';

const FULLSCREEN_VERT = `#version 300 es
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
`;

// One pass added to the accumulation: by blending (u_previousWeight 0), or, where float32 targets
// cannot blend, by reading the previous sum from the other target of a ping-pong pair.
const ACCUMULATE_FRAG = `#version 300 es
precision highp float;
precision highp sampler2D;
uniform sampler2D u_pass;
uniform sampler2D u_previous;
uniform float u_previousWeight;
out vec4 o_colour;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    o_colour = texelFetch(u_pass, p, 0);
    if (u_previousWeight != 0.0) o_colour += u_previousWeight * texelFetch(u_previous, p, 0);
}
`;

const DISPLAY_FRAG = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform sampler2D u_left;      // mode A (pixels x < u_split)
uniform sampler2D u_right;     // mode B (pixels x >= u_split)
uniform float u_leftScale;     // 1, or 1 / samples for a summed reference
uniform float u_rightScale;
uniform int u_split;           // first column of mode B (the width when there is no split)
uniform int u_divider;         // draw the divider line
uniform vec3 u_background;     // linear RGB
out vec4 o_colour;

float oetf(float x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = p.x >= u_split ? texelFetch(u_right, p, 0) * u_rightScale : texelFetch(u_left, p, 0) * u_leftScale;
    vec3 rgb = clamp(c.rgb + (1.0 - c.a) * u_background, 0.0, 1.0);
    rgb = vec3(oetf(rgb.r), oetf(rgb.g), oetf(rgb.b));
    if (u_divider != 0 && (p.x == u_split || p.x == u_split - 1)) {
        rgb = p.x == u_split ? vec3(1.0) : vec3(0.0);
    }
    o_colour = vec4(rgb, 1.0);
}
`;

export class Passes {
  /** caps: detectExtensions' result; its `target` is the format of both targets. */
  constructor(gl, caps) {
    this.gl = gl;
    this.format = caps.target;
    // The reference is a float32 sum of passes wherever float32 is renderable: blended if float32 can
    // blend, else ping-ponged between two targets. Without float32 targets (16F, RGBA8) it is a running
    // mean (blend constant 1 / (n + 1)), which cannot overflow but stalls once the weight gets below
    // the format's precision: the low-precision fallbacks.
    this.accumFormat = caps.ext.colorBufferFloat ? 'RGBA32F' : this.format;
    this.accumMode = this.accumFormat !== 'RGBA32F' ? 'mean' : caps.ext.floatBlend ? 'blend' : 'pingpong';
    // a 16F running mean stalls beyond ~64 samples (its 1 / (n + 1) steps fall under half an ulp)
    this.maxSamples = this.accumMode === 'mean' ? 64 : Infinity;
    this.vao = gl.createVertexArray();
    this.accumulateProgram = compileProgram(gl, FULLSCREEN_VERT, ACCUMULATE_FRAG, 'accumulate pass');
    this.displayProgram = compileProgram(gl, FULLSCREEN_VERT, DISPLAY_FRAG, 'display pass');
    const loc = (prog, names) => Object.fromEntries(names.map((n) => [n, gl.getUniformLocation(prog, n)]));
    this.accLoc = loc(this.accumulateProgram, ['u_pass', 'u_previous', 'u_previousWeight']);
    this.dispLoc = loc(this.displayProgram, [
      'u_left', 'u_right', 'u_leftScale', 'u_rightScale', 'u_split', 'u_divider', 'u_background',
    ]);
    this.colour = null;
    this.accum = null; // the target holding the current sum or mean
    this.spare = null; // ping-pong only: the other one
    this.samples = 0;
  }

  /** (Re)create the targets at the render size. */
  resize(width, height) {
    if (this.colour && this.colour.width === width && this.colour.height === height) return;
    this.release();
    this.colour = createRenderTarget(this.gl, this.format, width, height, true);
    this.accum = createRenderTarget(this.gl, this.accumFormat, width, height, false);
    if (this.accumMode === 'pingpong') this.spare = createRenderTarget(this.gl, this.accumFormat, width, height, false);
    this.samples = 0;
  }

  resetAccumulation() {
    this.samples = 0;
  }

  /** Add the colour target (one jittered `point` pass) to the accumulation target. */
  accumulate() {
    const gl = this.gl;
    const pingpong = this.accumMode === 'pingpong' && this.samples > 0;
    const target = pingpong ? this.spare : this.accum;
    gl.bindFramebuffer(gl.FRAMEBUFFER, target.framebuffer);
    gl.viewport(0, 0, target.width, target.height);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.CULL_FACE);
    gl.disable(gl.SCISSOR_TEST);
    gl.disable(gl.BLEND); // first pass (it replaces whatever was there) and ping-pong
    if (this.samples > 0 && this.accumMode === 'blend') {
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.ONE, gl.ONE);
    } else if (this.samples > 0 && this.accumMode === 'mean') {
      gl.enable(gl.BLEND);
      gl.blendColor(0, 0, 0, 1 / (this.samples + 1));
      gl.blendFunc(gl.CONSTANT_ALPHA, gl.ONE_MINUS_CONSTANT_ALPHA);
    }
    gl.useProgram(this.accumulateProgram);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.colour.texture);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, pingpong ? this.accum.texture : this.colour.texture); // unread without ping-pong
    gl.uniform1i(this.accLoc.u_pass, 0);
    gl.uniform1i(this.accLoc.u_previous, 1);
    gl.uniform1f(this.accLoc.u_previousWeight, pingpong ? 1 : 0);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
    gl.bindTexture(gl.TEXTURE_2D, null); // unit 1
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, null); // no feedback loop when the scene draws into it again
    gl.disable(gl.BLEND);
    if (pingpong) [this.accum, this.spare] = [this.spare, this.accum];
    this.samples++;
  }

  /** What a side of the display shows: the scene target, or the accumulated reference. */
  source(reference) {
    if (!reference) return { texture: this.colour.texture, scale: 1 };
    return { texture: this.accum.texture, scale: this.accumMode === 'mean' ? 1 : 1 / Math.max(1, this.samples) };
  }

  /**
   * Composite into the canvas. left/right: source() results; split: first column of `right`
   * (the width for no split); divider: draw the line; background: linear RGB.
   */
  display(left, right, split, divider, background) {
    const gl = this.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, this.colour.width, this.colour.height);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.CULL_FACE);
    gl.disable(gl.BLEND);
    gl.disable(gl.SCISSOR_TEST);
    gl.useProgram(this.displayProgram);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, left.texture);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, right.texture);
    const u = this.dispLoc;
    gl.uniform1i(u.u_left, 0);
    gl.uniform1i(u.u_right, 1);
    gl.uniform1f(u.u_leftScale, left.scale);
    gl.uniform1f(u.u_rightScale, right.scale);
    gl.uniform1i(u.u_split, split);
    gl.uniform1i(u.u_divider, divider ? 1 : 0);
    gl.uniform3f(u.u_background, background[0], background[1], background[2]);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  release() {
    for (const target of [this.colour, this.accum, this.spare]) if (target) target.release();
    this.colour = this.accum = this.spare = null;
  }
}
