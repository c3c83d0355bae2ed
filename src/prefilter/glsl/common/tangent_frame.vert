// Shared vertex stage of materials shaded in the tangent frame (normals/, diffraction/): world normal,
// world tangent frame and the vector to the eye, for light and view directions in the tangent frame.
// u_jitter is a sub-pixel offset of the projection in NDC units (reference supersampling passes).
in vec3 in_pos;
in vec3 in_nrm;
in vec4 in_tan;
in vec2 in_uv;

uniform mat4 u_clipFromObject;
uniform mat3 u_worldNormalFromObject;
uniform mat4 u_objectFromWorld;
uniform vec4 u_eyeObject;  // the eye (w = 1) or, for orthographic cameras, the view direction (w = 0)
uniform vec2 u_jitter;

out vec3 v_normal;
out vec4 v_tangent;  // xyz world, w handedness: bitangent = w cross(normal, tangent)
out vec3 v_toEye;    // world, unnormalised
out vec2 v_uv;

void main() {
    vec4 clip = u_clipFromObject * vec4(in_pos, 1.0);
    clip.xy += u_jitter * clip.w;
    gl_Position = clip;
    mat4 worldFromObject = inverse(u_objectFromWorld);
    v_normal = u_worldNormalFromObject * in_nrm;
    v_tangent = vec4(mat3(worldFromObject) * in_tan.xyz, in_tan.w);
    vec3 eye = (worldFromObject * u_eyeObject).xyz;
    v_toEye = u_eyeObject.w > 0.5 ? eye - (worldFromObject * vec4(in_pos, 1.0)).xyz : -eye;
    v_uv = in_uv;
}
