// SPDX-License-Identifier: MIT
// Shared lighting of meshes and splats (mesh.frag, splat.frag,
// splat_accumulate.frag pull it in with #include "lighting.glsl", which the
// C renderer and the web viewer expand before compiling: GLSL ES 1.00 has no
// include of its own). Two-sided Phong with a headlight and a key light, in
// eye space.
uniform vec3 u_key_direction;   // unit vector towards the key light, eye space

const float ambient = 0.12;
const float headlight = 0.55;
const float key_light = 0.45;
const float specular_strength = 0.22;
const float shininess = 40.0;

float phong(vec3 normal, vec3 to_light, vec3 to_eye, out float specular)
{
    float diffuse = max(dot(normal, to_light), 0.0);
    vec3 reflected = reflect(-to_light, normal);
    specular = diffuse > 0.0 ? pow(max(dot(reflected, to_eye), 0.0), shininess) : 0.0;
    return diffuse;
}

// Light whichever side faces the camera: testing the normal against the view
// (rather than gl_FrontFacing) also copes with meshes whose winding disagrees
// with their stored normals, and with splats drawn without culling.
vec3 shade(vec3 normal, vec3 to_eye, vec3 base)
{
    if (dot(normal, to_eye) < 0.0) normal = -normal;
    float head_specular, key_specular;
    float head_diffuse = phong(normal, to_eye, to_eye, head_specular);
    float key_diffuse = phong(normal, u_key_direction, to_eye, key_specular);
    vec3 lit = base * (ambient + headlight * head_diffuse + key_light * key_diffuse)
             + vec3(specular_strength * (0.5 * head_specular + key_specular));
    return min(lit, vec3(1.0));
}
