/* lopview-gl: draw a .lop with the shipped GLSL decoders (OpenGL 4.3 core, headless EGL) into a PNG.

   lopview-gl FILE.lop OUT.png --level B --eye X,Y,Z --target X,Y,Z [--lod K] [--size WxH]
              [--fov DEG] [--near N --far F] [--mvp 16 row-major numbers] [--samples N]
              [--phong AMBIENT,DIFFUSE,KS,SHININESS] [--base GREY] [--shaders DIR]

   Per buffer it uploads what lop.h builds: P and the LopDecode block (SSBO 0, UBO 0; the cluster
   records as SSBO 3 with #define LOP_CLUSTERED), the attribute record as stored and its
   LopAttributeDecode block (SSBO 1, UBO 2), the indices; the vertex shader is
   shaders/decode_bitplanes.glsl + decode_attributes.glsl as shipped, then a placement's rows and
   the camera. Phong with a headlight, as lopcook's render harness (lopcook/verify/glsl.py) shades;
   back faces culled; MSAA resolved by a blit; RGBA8 PNG, alpha = coverage. A placement's buffer
   is drawn at the highest level its placements ask for (clamp(B + level_shift, 1, 24)).
   Exit 0, or 2 with one line on stderr. Build: make -C runtime/c view (-lEGL -lGL). */
#define _POSIX_C_SOURCE 200809L
#define GL_GLEXT_PROTOTYPES 1
#define LOP_IMPLEMENTATION
#include "../lop.h"
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/gl.h>
#include <GL/glext.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *VS_MAIN =
    "uniform mat4 u_mvp; uniform vec4 u_place0, u_place1, u_place2; uniform mat3 u_nmat;\n"
    "out vec3 v_pos; out vec3 v_normal; out vec2 v_uv; out vec4 v_color;\n"
    "void main() {\n uint j = uint(gl_VertexID); uvec3 g; vec3 p; uint bits; lop_decode(j, g, p, bits);\n"
    " precise vec3 w;\n w.x = ((u_place0.x * p.x + u_place0.y * p.y) + u_place0.z * p.z) + u_place0.w;\n"
    " w.y = ((u_place1.x * p.x + u_place1.y * p.y) + u_place1.z * p.z) + u_place1.w;\n"
    " w.z = ((u_place2.x * p.x + u_place2.y * p.y) + u_place2.z * p.z) + u_place2.w;\n"
    " v_pos = w;\n v_normal = lop_attr_bits.x != 0u ? normalize(u_nmat * normalize(lop_decode_normal(j))) : vec3(0.0);\n"
    " v_uv = lop_attr_bits.y != 0u ? lop_decode_uv(j) : vec2(0.0);\n"
    " v_color = lop_attr_bits.z != 0u ? lop_decode_color(j) : vec4(1.0);\n gl_Position = u_mvp * vec4(w, 1.0);\n}\n";
static const char *FS = /* lopcook/verify/glsl.py FS, without the part-ID output and textures */
    "#version 430\nin vec3 v_pos; in vec3 v_normal; in vec2 v_uv; in vec4 v_color;\n"
    "uniform vec3 u_eye; uniform vec3 u_light; uniform vec4 u_phong; uniform vec3 u_base;\n"
    "uniform int u_has_normal; uniform int u_has_color; layout(location = 0) out vec4 o_color;\n"
    "void main() {\n vec3 V = normalize(u_eye - v_pos); vec3 N; float len = length(v_normal);\n"
    " if (u_has_normal != 0 && len > 1e-12) { N = v_normal / len; } else {\n"
    "  N = normalize(cross(dFdx(v_pos), dFdy(v_pos))); N = dot(N, V) < 0.0 ? -N : N; }\n"
    " vec3 base = u_has_color != 0 ? vec3(1.0) : u_base; if (u_has_color != 0) base *= v_color.rgb;\n"
    " float nl = dot(N, u_light); vec3 R = reflect(-u_light, N);\n"
    " float spec = nl > 0.0 ? u_phong.z * pow(max(dot(R, V), 0.0), u_phong.w) : 0.0;\n"
    " vec3 c = base * (u_phong.x + u_phong.y * max(nl, 0.0)) + vec3(spec);\n o_color = vec4(clamp(c, 0.0, 1.0), 1.0);\n}\n";

static int fail(const char *what, const char *detail)
{
    fprintf(stderr, "lopview-gl: %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(2);
}

static char *slurp(const char *path, size_t *size)
{
    FILE *fh = fopen(path, "rb");
    char *buf;
    long n;
    if (!fh || fseek(fh, 0, SEEK_END) || (n = ftell(fh)) < 0 || fseek(fh, 0, SEEK_SET) || !(buf = malloc((size_t)n + 1)) ||
        fread(buf, 1, (size_t)n, fh) != (size_t)n)
        fail("cannot read", path);
    fclose(fh);
    buf[n] = 0;
    *size = (size_t)n;
    return buf;
}

static void numbers(const char *s, double *v, int n, const char *flag)
{
    int i;
    for (i = 0; i < n; i++) {
        char *end;
        v[i] = strtod(s, &end);
        if (end == s || (i + 1 < n ? *end != ',' : *end != 0))
            fail("expected comma-separated numbers for", flag);
        s = end + 1;
    }
}

static GLuint program(const char *dir, int clustered)
{
    char path[4096], log[2048];
    size_t n;
    const char *vs[5], *fs[1] = {FS};
    GLuint p = glCreateProgram(), v = glCreateShader(GL_VERTEX_SHADER), f = glCreateShader(GL_FRAGMENT_SHADER);
    GLint ok;
    vs[0] = clustered ? "#version 430\n#define LOP_NO_VIEW\n#define LOP_CLUSTERED\n" : "#version 430\n#define LOP_NO_VIEW\n";
    snprintf(path, sizeof path, "%s/decode_bitplanes.glsl", dir);
    vs[1] = slurp(path, &n);
    snprintf(path, sizeof path, "%s/decode_attributes.glsl", dir);
    vs[2] = slurp(path, &n);
    vs[3] = VS_MAIN;
    glShaderSource(v, 4, vs, NULL);
    glShaderSource(f, 1, fs, NULL);
    glCompileShader(v);
    glCompileShader(f);
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetShaderInfoLog(v, sizeof log, NULL, log);
        fail("the decoders do not compile", log);
    }
    return p;
}

static GLuint buffer(GLenum target, GLuint binding, const void *data, size_t size)
{
    GLuint b;
    static const uint32_t zero[4] = {0, 0, 0, 0};
    glGenBuffers(1, &b);
    glBindBuffer(target, b);
    glBufferData(target, size ? (GLsizeiptr)size : 16, size ? data : zero, GL_STATIC_DRAW);
    if (binding != ~0u)
        glBindBufferBase(target, binding, b);
    return b;
}

static void put32(FILE *fh, uint32_t v)
{
    unsigned char b[4] = {(unsigned char)(v >> 24), (unsigned char)(v >> 16), (unsigned char)(v >> 8), (unsigned char)v};
    fwrite(b, 1, 4, fh);
}

static uint32_t crc(uint32_t c, const unsigned char *p, size_t n)
{
    int k;
    c = ~c;
    while (n--)
        for (c ^= *p++, k = 0; k < 8; k++)
            c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    return ~c;
}

/* A PNG of stored (uncompressed) deflate blocks: RGBA8, rows top first. */
static void write_png(const char *path, const unsigned char *rgba, int w, int h)
{
    size_t row = 4 * (size_t)w + 1, raw = row * (size_t)h, blocks = (raw + 65534) / 65535, len = 2 + raw + 5 * blocks + 4;
    unsigned char *z = malloc(len + 8), *r = malloc(raw), ihdr[17] = "IHDR";
    uint32_t a = 1, b = 0;
    size_t i, o = 0;
    FILE *fh = fopen(path, "wb");
    if (!fh || !z || !r)
        fail("cannot write", path);
    for (i = 0; i < (size_t)h; i++) {
        r[i * row] = 0;
        memcpy(r + i * row + 1, rgba + 4 * (size_t)w * i, 4 * (size_t)w);
    }
    z[o++] = 0x78;
    z[o++] = 0x01;
    for (i = 0; i < raw; i += 65535) {
        size_t n = raw - i < 65535 ? raw - i : 65535;
        z[o++] = (unsigned char)(i + n == raw);
        z[o++] = (unsigned char)n, z[o++] = (unsigned char)(n >> 8), z[o++] = (unsigned char)~n, z[o++] = (unsigned char)(~n >> 8);
        memcpy(z + o, r + i, n);
        o += n;
    }
    for (i = 0; i < raw; i++)
        a = (a + r[i]) % 65521, b = (b + a) % 65521;
    z[o++] = (unsigned char)(b >> 8), z[o++] = (unsigned char)b, z[o++] = (unsigned char)(a >> 8), z[o++] = (unsigned char)a;
    fwrite("\x89PNG\r\n\x1a\n", 1, 8, fh);
    ihdr[4] = (unsigned char)(w >> 24), ihdr[5] = (unsigned char)(w >> 16), ihdr[6] = (unsigned char)(w >> 8), ihdr[7] = (unsigned char)w;
    ihdr[8] = (unsigned char)(h >> 24), ihdr[9] = (unsigned char)(h >> 16), ihdr[10] = (unsigned char)(h >> 8), ihdr[11] = (unsigned char)h;
    ihdr[12] = 8, ihdr[13] = 6, ihdr[14] = ihdr[15] = ihdr[16] = 0;
    put32(fh, 13), fwrite(ihdr, 1, 17, fh), put32(fh, crc(0, ihdr, 17));
    put32(fh, (uint32_t)o), fwrite("IDAT", 1, 4, fh), fwrite(z, 1, o, fh), put32(fh, crc(crc(0, (const unsigned char *)"IDAT", 4), z, o));
    put32(fh, 0), fwrite("IEND", 1, 4, fh), put32(fh, crc(0, (const unsigned char *)"IEND", 4));
    if (fclose(fh))
        fail("cannot write", path);
    free(z), free(r);
}

int main(int argc, char **argv)
{
    const char *in = NULL, *out = NULL, *shaders = "shaders";
    double eye[3], tgt[3], fov = 60.0, nearz = -1, farz = -1, mvp[16], phong[4] = {0.15, 0.65, 0.5, 32.0}, base = 0.8;
    int level = 0, w = 512, h = 512, samples = 4, have_eye = 0, have_tgt = 0, have_mvp = 0, a, k;
    long lod = 0;
    uint32_t i;
    size_t size;
    char *data;
    lop_file *f;
    lop_message msg;
    lop_options opt;
    for (a = 1; a < argc; a++) {
        const char *s = argv[a], *v = a + 1 < argc ? argv[a + 1] : NULL;
        if (s[0] != '-') { if (!in) in = s; else if (!out) out = s; else fail("unexpected argument", s); continue; }
        if (!v) fail("missing value for", s);
        a++;
        if (!strcmp(s, "--level")) level = atoi(v);
        else if (!strcmp(s, "--lod")) lod = atol(v);
        else if (!strcmp(s, "--eye")) numbers(v, eye, 3, s), have_eye = 1;
        else if (!strcmp(s, "--target")) numbers(v, tgt, 3, s), have_tgt = 1;
        else if (!strcmp(s, "--mvp")) numbers(v, mvp, 16, s), have_mvp = 1;
        else if (!strcmp(s, "--size")) { if (sscanf(v, "%dx%d", &w, &h) != 2 || w < 1 || h < 1 || w > 16384 || h > 16384) fail("--size WxH", v); }
        else if (!strcmp(s, "--fov")) fov = atof(v);
        else if (!strcmp(s, "--near")) nearz = atof(v);
        else if (!strcmp(s, "--far")) farz = atof(v);
        else if (!strcmp(s, "--samples")) samples = atoi(v);
        else if (!strcmp(s, "--phong")) numbers(v, phong, 4, s);
        else if (!strcmp(s, "--base")) base = atof(v);
        else if (!strcmp(s, "--shaders")) shaders = v;
        else fail("unknown option", s);
    }
    if (!in || !out || !have_eye || !have_tgt || level < 1 || level > 24 || lod < 0)
        fail("usage: lopview-gl FILE.lop OUT.png --level B (1..24) --eye X,Y,Z --target X,Y,Z [options]", NULL);
    data = slurp(in, &size);
    memset(&opt, 0, sizeof opt);
    if (lop_open(data, size, &opt, &f, &msg) != lop_success)
        fail(in, msg.text);
    if (level > f->available_level)
        fail("level not in this file", in);
    {   /* headless EGL, OpenGL 4.3 core: Mesa's surfaceless platform, else the default display,
           else the first EGL device (a GPU driver without a window system) */
        PFNEGLGETPLATFORMDISPLAYEXTPROC gpd = (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
        PFNEGLQUERYDEVICESEXTPROC qd = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
        EGLint n = 0, cfg_attr[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
        EGLint ctx_attr[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                             EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
        EGLDeviceEXT dev;
        EGLDisplay d = gpd ? gpd(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL) : EGL_NO_DISPLAY;
        EGLConfig cfg;
        EGLContext c = EGL_NO_CONTEXT;
        if (d == EGL_NO_DISPLAY || !eglInitialize(d, NULL, NULL))
            d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
        if ((d == EGL_NO_DISPLAY || !eglInitialize(d, NULL, NULL)) && gpd && qd && qd(1, &dev, &n) && n > 0)
            d = gpd(EGL_PLATFORM_DEVICE_EXT, dev, NULL);
        if (d != EGL_NO_DISPLAY && eglInitialize(d, NULL, NULL) && eglBindAPI(EGL_OPENGL_API) &&
            eglChooseConfig(d, cfg_attr, &cfg, 1, &n) && n > 0)
            c = eglCreateContext(d, cfg, EGL_NO_CONTEXT, ctx_attr);
        if (c == EGL_NO_CONTEXT || !eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, c))
            fail("no OpenGL 4.3 context through EGL (install libegl1 and Mesa, or a GPU driver)", NULL);
    }
    if (!have_mvp) { /* lopcook.verify.cameras: perspective(fov, w/h, near, far) @ look_at(eye, target) */
        double fw[3], s[3], u[3], l = 0, up[3] = {0, 1, 0}, t = 1.0 / tan(fov * 3.141592653589793 / 360.0), ls = 0;
        double view[16] = {0}, proj[16] = {0};
        int r, c2;
        for (k = 0; k < 3; k++) fw[k] = tgt[k] - eye[k], l += fw[k] * fw[k];
        for (k = 0; k < 3; k++) fw[k] /= sqrt(l);
        if (fabs(fw[1]) >= 0.99) up[1] = 0, up[2] = 1;
        s[0] = fw[1] * up[2] - fw[2] * up[1], s[1] = fw[2] * up[0] - fw[0] * up[2], s[2] = fw[0] * up[1] - fw[1] * up[0];
        for (k = 0; k < 3; k++) ls += s[k] * s[k];
        for (k = 0; k < 3; k++) s[k] /= sqrt(ls);
        u[0] = s[1] * fw[2] - s[2] * fw[1], u[1] = s[2] * fw[0] - s[0] * fw[2], u[2] = s[0] * fw[1] - s[1] * fw[0];
        for (k = 0; k < 3; k++) {
            view[k] = s[k], view[4 + k] = u[k], view[8 + k] = -fw[k];
            view[3] -= s[k] * eye[k], view[7] -= u[k] * eye[k], view[11] += fw[k] * eye[k];
        }
        view[15] = 1;
        if (nearz <= 0) nearz = sqrt(l) * 1e-3;
        if (farz <= nearz) farz = sqrt(l) + 2.0 * f->grid_extent * 1.7320508075688772;
        proj[0] = t * h / w, proj[5] = t, proj[10] = (farz + nearz) / (nearz - farz), proj[11] = 2 * farz * nearz / (nearz - farz), proj[14] = -1;
        for (r = 0; r < 4; r++)
            for (c2 = 0; c2 < 4; c2++)
                for (mvp[4 * r + c2] = 0, k = 0; k < 4; k++) mvp[4 * r + c2] += proj[4 * r + k] * view[4 * k + c2];
    }
    {
        GLuint progs[2] = {program(shaders, 0), program(shaders, 1)}, vao, fbo[2], rb[3];
        GLfloat m[16], light[3];
        unsigned char *rgba = malloc(8 * (size_t)w * h);
        double ll = 0;
        for (k = 0; k < 16; k++) m[k] = (GLfloat)mvp[k];
        for (k = 0; k < 3; k++) light[k] = (GLfloat)(eye[k] - tgt[k]), ll += (eye[k] - tgt[k]) * (eye[k] - tgt[k]);
        for (k = 0; k < 3; k++) light[k] = (GLfloat)((eye[k] - tgt[k]) / sqrt(ll));
        glGenVertexArrays(1, &vao), glBindVertexArray(vao);
        glGenRenderbuffers(3, rb), glGenFramebuffers(2, fbo);
        glBindRenderbuffer(GL_RENDERBUFFER, rb[0]), glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA8, w, h);
        glBindRenderbuffer(GL_RENDERBUFFER, rb[1]), glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH_COMPONENT24, w, h);
        glBindRenderbuffer(GL_RENDERBUFFER, rb[2]), glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo[0]);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[0]);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb[1]);
        glViewport(0, 0, w, h), glClearColor(0, 0, 0, 0), glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST), glEnable(GL_CULL_FACE), glCullFace(GL_BACK), glFrontFace(GL_CCW);
        for (i = 0; i < f->part_count; i++) {
            const lop_part *pt = &f->parts[i];
            uint32_t kk = (uint32_t)lod < pt->lod_count ? (uint32_t)lod : pt->lod_count - 1, j, *idx, *words, *rec;
            const lop_lod *e = &pt->lods[kk];
            int lvl = lop_part_level(f, i, level), clustered;
            unsigned char block[LOP_CLUSTERED_BLOCK_SIZE], ablock[LOP_ATTRIBUTE_BLOCK_SIZE];
            const uint8_t *attr;
            size_t abytes;
            lop_buffer_info info;
            GLuint bufs[6], prog;
            GLfloat nm[9], det;
            const float *A = pt->transform;
            for (j = 0; j < f->part_count; j++) /* the shared buffer: resident at its placements' highest level */
                if (f->parts[j].owner == pt->owner && lop_part_level(f, j, level) > lvl)
                    lvl = lop_part_level(f, j, level);
            if (lop_buffer(f, i, kk, lvl, LOP_LAYOUT_NATIVE, &info) != lop_success)
                fail("cannot build the buffers of", pt->name);
            words = malloc(4 * (size_t)info.words + 4), rec = malloc(16 * (size_t)info.clusters + 16);
            idx = malloc(12 * (size_t)e->triangles);
            if (lop_build(f, i, kk, lvl, LOP_LAYOUT_NATIVE, words, (size_t)info.words, rec, 4 * (size_t)info.clusters) ||
                lop_decode_block(f, i, kk, lvl, LOP_LAYOUT_NATIVE, block, sizeof block) ||
                lop_attribute_block(f, i, kk, ablock, sizeof ablock) || lop_attribute_words(f, i, kk, &attr, &abytes) ||
                lop_decode_indices(f, i, kk, idx, 3 * (size_t)e->triangles))
                fail("cannot build the buffers of", pt->name);
            clustered = info.clustered;
            prog = progs[clustered];
            glUseProgram(prog);
            bufs[0] = buffer(GL_SHADER_STORAGE_BUFFER, 0, words, 4 * (size_t)info.words);
            bufs[1] = buffer(GL_UNIFORM_BUFFER, 0, block, info.block_size);
            bufs[2] = buffer(GL_SHADER_STORAGE_BUFFER, 3, rec, 16 * (size_t)info.clusters);
            bufs[3] = buffer(GL_SHADER_STORAGE_BUFFER, 1, attr, abytes);
            bufs[4] = buffer(GL_UNIFORM_BUFFER, 2, ablock, sizeof ablock);
            bufs[5] = buffer(GL_ELEMENT_ARRAY_BUFFER, ~0u, idx, 12 * (size_t)e->triangles);
            /* normal matrix A^-T (cofactors of A over its determinant) */
            det = A[0] * (A[5] * A[10] - A[6] * A[9]) - A[1] * (A[4] * A[10] - A[6] * A[8]) + A[2] * (A[4] * A[9] - A[5] * A[8]);
            nm[0] = (A[5] * A[10] - A[6] * A[9]) / det, nm[3] = -(A[4] * A[10] - A[6] * A[8]) / det, nm[6] = (A[4] * A[9] - A[5] * A[8]) / det;
            nm[1] = -(A[1] * A[10] - A[2] * A[9]) / det, nm[4] = (A[0] * A[10] - A[2] * A[8]) / det, nm[7] = -(A[0] * A[9] - A[1] * A[8]) / det;
            nm[2] = (A[1] * A[6] - A[2] * A[5]) / det, nm[5] = -(A[0] * A[6] - A[2] * A[4]) / det, nm[8] = (A[0] * A[5] - A[1] * A[4]) / det;
            glUniformMatrix4fv(glGetUniformLocation(prog, "u_mvp"), 1, GL_TRUE, m);
            glUniformMatrix3fv(glGetUniformLocation(prog, "u_nmat"), 1, GL_FALSE, nm);
            glUniform4f(glGetUniformLocation(prog, "u_place0"), A[0], A[1], A[2], A[3]);
            glUniform4f(glGetUniformLocation(prog, "u_place1"), A[4], A[5], A[6], A[7]);
            glUniform4f(glGetUniformLocation(prog, "u_place2"), A[8], A[9], A[10], A[11]);
            glUniform3f(glGetUniformLocation(prog, "u_eye"), (GLfloat)eye[0], (GLfloat)eye[1], (GLfloat)eye[2]);
            glUniform3fv(glGetUniformLocation(prog, "u_light"), 1, light);
            glUniform4f(glGetUniformLocation(prog, "u_phong"), (GLfloat)phong[0], (GLfloat)phong[1], (GLfloat)phong[2], (GLfloat)phong[3]);
            glUniform3f(glGetUniformLocation(prog, "u_base"), (GLfloat)base, (GLfloat)base, (GLfloat)base);
            glUniform1i(glGetUniformLocation(prog, "u_has_normal"), e->normal_bits != 0);
            glUniform1i(glGetUniformLocation(prog, "u_has_color"), e->color_bits != 0);
            glDrawElements(GL_TRIANGLES, (GLsizei)(3 * e->triangles), GL_UNSIGNED_INT, NULL);
            glFinish();
            glDeleteBuffers(6, bufs);
            free(words), free(rec), free(idx);
        }
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo[0]), glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo[1]);
        glFramebufferRenderbuffer(GL_DRAW_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[2]);
        glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo[1]);
        glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba + 4 * (size_t)w * h);
        for (k = 0; k < h; k++) /* rows top first */
            memcpy(rgba + 4 * (size_t)w * k, rgba + 4 * (size_t)w * h + 4 * (size_t)w * (h - 1 - k), 4 * (size_t)w);
        if (glGetError() != GL_NO_ERROR)
            fail("OpenGL reported an error", NULL);
        write_png(out, rgba, w, h);
    }
    lop_close(f);
    return 0;
}
