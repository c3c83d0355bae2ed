// Shared vertex stage: object -> clip, world normal, solid texture coordinate s and uv.
// u_jitter is a sub-pixel offset of the projection in NDC units (reference supersampling passes).
in vec3 in_pos;
in vec3 in_nrm;
in vec2 in_uv;

uniform mat4 u_clipFromObject;
uniform mat3 u_worldNormalFromObject;
uniform mat4 u_solidFromObject;
uniform vec2 u_jitter;

out vec3 v_solid;
out vec3 v_normal;
out vec2 v_uv;

void main() {
    vec4 clip = u_clipFromObject * vec4(in_pos, 1.0);
    clip.xy += u_jitter * clip.w;
    gl_Position = clip;
    v_solid = (u_solidFromObject * vec4(in_pos, 1.0)).xyz;
    v_normal = u_worldNormalFromObject * in_nrm;
    v_uv = in_uv;
}
