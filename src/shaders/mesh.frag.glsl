// Two-sided Phong shading with a headlight and a key light (eye space).
precision mediump float;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;

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

void main()
{
    vec3 normal = normalize(v_normal);
    vec3 to_eye = normalize(v_to_eye);
    // Two-sided: light whichever side faces the camera. Testing the normal
    // against the view (rather than gl_FrontFacing) also copes with meshes
    // whose winding disagrees with their stored normals.
    if (dot(normal, to_eye) < 0.0) normal = -normal;
    float head_specular, key_specular;
    float head_diffuse = phong(normal, to_eye, to_eye, head_specular);
    float key_diffuse = phong(normal, u_key_direction, to_eye, key_specular);
    vec3 base = v_color.rgb;
    vec3 lit = base * (ambient + headlight * head_diffuse + key_light * key_diffuse)
             + vec3(specular_strength * (0.5 * head_specular + key_specular));
    gl_FragColor = vec4(min(lit, vec3(1.0)), 1.0);
}
