// 1-pass Phong splats: lit with the splat's normal (the lights of
// mesh.frag.glsl), alpha from the Gaussian kernel texture (the paper's
// Fig. 1), blended over what is already drawn.
precision mediump float;

uniform sampler2D u_kernel;
uniform vec3 u_key_direction;   // unit vector towards the key light, eye space

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;

// The lighting of mesh.frag.glsl (keep the two in step: GLSL ES 1.00 has no
// #include), so that splats and meshes of one model look alike.
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

vec3 shade(vec3 normal, vec3 to_eye, vec3 base)
{
    if (dot(normal, to_eye) < 0.0) normal = -normal; // two-sided, as meshes (culling off)
    float head_specular, key_specular;
    float head_diffuse = phong(normal, to_eye, to_eye, head_specular);
    float key_diffuse = phong(normal, u_key_direction, to_eye, key_specular);
    vec3 lit = base * (ambient + headlight * head_diffuse + key_light * key_diffuse)
             + vec3(specular_strength * (0.5 * head_specular + key_specular));
    return min(lit, vec3(1.0));
}

void main()
{
    vec2 offset = gl_PointCoord * 2.0 - 1.0;
    if (dot(offset, offset) > 1.0) discard;
    float alpha = texture2D(u_kernel, gl_PointCoord).a;
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), v_color.rgb), alpha);
}
