/* python/seamtex/pysample.c - Client.sample and Client.sample_dir: arrays in through the
 * buffer protocol, arrays out, no per-query Python object.
 *
 * Owns: reading query columns (face, u, v, derivatives; directions) from any object with the
 * buffer protocol (numpy arrays, array.array, memoryview, bytes-like; strided or not) or from
 * a Python number broadcast to every query; checking their types, lengths and values; the
 * option names (mode, filter, format, zero rule: from the protocol's lists); packing the
 * stc_query array, the stc_sample call and copying its result out, all with the GIL
 * released.
 * Does not own: batching against the server's max_batch and pipelining (stc_sample does it).
 *
 * Rules (docs/python.md): face takes integer formats (b h i l q and unsigned), each value
 * 0..2^32-1; a numpy scalar or 0-d array is a number, like a Python one; u, v, derivatives and directions take float32 'f' or float64 'd' (converted to
 * float32, the wire type). Native or little-endian byte order. Mismatched lengths raise
 * ValueError. A NaN or infinity raises ValueError (naming the array and index) unless
 * nonfinite='status', which sends it and lets the server answer NONFINITE for that query.
 */
#include "pyseamtex.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"

/* ---- columns ------------------------------------------------------------------------------------ */

enum { COL_NONE, COL_SCALAR, COL_F32, COL_F64, COL_INT, COL_UINT };

typedef struct col {
    const char *name;
    Py_buffer   view;
    int         held;            /* view must be released */
    int         kind;            /* COL_* */
    int         isize;           /* item size of INT / UINT */
    double      f;               /* COL_SCALAR */
    long long   i;
    const char *p;
    Py_ssize_t  n, s0, s1;       /* elements, stride between them, stride between components */
} col;

static void col_release(col *c)
{
    if (c->held)
        PyBuffer_Release(&c->view);
    c->held = 0;
}

/* Number o (a Python int or float, a numpy scalar, a 0-d array) as a broadcast column: an
 * integer (a face id 0..2^32-1) when is_int, else a float. */
static int scalar_get(PyObject *o, const char *name, int is_int, col *c)
{
    c->kind = COL_SCALAR;
    if (!is_int) {
        c->f = PyFloat_AsDouble(o);
        return c->f == -1.0 && PyErr_Occurred() ? -1 : 0;
    }
    PyObject *ix = PyNumber_Index(o);
    if (!ix)
        return -1;
    int over = 0;
    c->i = PyLong_AsLongLongAndOverflow(ix, &over);
    Py_DECREF(ix);
    if (c->i == -1 && PyErr_Occurred())
        return -1;
    if (over || c->i < 0 || c->i > (long long)UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%s = %R is not a face id 0..2^32-1", name, o);
        return -1;
    }
    return 0;
}

/* o (None, a number, or a buffer) as column `name` of ncomp components (1, or 3 for
 * directions). is_int: integers wanted (face), else floats. */
static int col_get(PyObject *o, const char *name, int is_int, int ncomp, col *c)
{
    memset(c, 0, sizeof *c);
    c->name = name;
    c->n = -1;                   /* no length of its own */
    if (!o || o == Py_None)
        return 0;
    if (ncomp == 1 && (PyLong_Check(o) || (!is_int && PyFloat_Check(o))))
        return scalar_get(o, name, is_int, c);
    if (PyObject_GetBuffer(o, &c->view, PyBUF_RECORDS_RO) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s must be %s or an object with the buffer protocol "
                     "(numpy array, array.array, memoryview), not %.80s", name,
                     ncomp == 3 ? "an (n, 3) array" : is_int ? "an int" : "a number",
                     Py_TYPE(o)->tp_name);
        return -1;
    }
    c->held = 1;
    const char *f = c->view.format ? c->view.format : "B";
    if (*f == '@' || *f == '=')
        f++;
#if PY_LITTLE_ENDIAN
    else if (*f == '<')
        f++;
#endif
    char t = f[0] && !f[1] ? f[0] : 0;
    int ok = 0;
    if (is_int) {
        ok = 1;
        if (t == 'b' || t == 'h' || t == 'i' || t == 'l' || t == 'q')
            c->kind = COL_INT;
        else if (t == 'B' || t == 'H' || t == 'I' || t == 'L' || t == 'Q')
            c->kind = COL_UINT;
        else
            ok = 0;
        c->isize = (int)c->view.itemsize;
        if (ok && c->isize != 1 && c->isize != 2 && c->isize != 4 && c->isize != 8)
            ok = 0;
    } else if (t == 'f' && c->view.itemsize == 4) {
        c->kind = COL_F32;
        ok = 1;
    } else if (t == 'd' && c->view.itemsize == 8) {
        c->kind = COL_F64;
        ok = 1;
    }
    if (ncomp == 1 && c->view.ndim == 0 && !is_int && !ok &&
        (t == 'b' || t == 'h' || t == 'i' || t == 'l' || t == 'q' || t == 'B' || t == 'H' ||
         t == 'I' || t == 'L' || t == 'Q'))
        ok = 1;                  /* an integer scalar for a float column, as a Python int is */
    if (ok && ncomp == 1 && c->view.ndim == 0) {
        /* a numpy scalar (np.uint32(3), np.float32(0.5), arr[i]) or a 0-d array: a number,
         * broadcast like a Python one; read through the number protocol */
        col_release(c);
        return scalar_get(o, name, is_int, c);
    }
    if (!ok) {
        PyErr_Format(PyExc_TypeError, "%s must hold %s in native byte order, not format '%s'",
                     name, is_int ? "integers (uint32 or int)" : "float32 or float64",
                     c->view.format ? c->view.format : "B");
        col_release(c);
        return -1;
    }
    c->p = c->view.buf;
    if (ncomp == 1 && c->view.ndim == 1) {
        c->n = c->view.shape[0];
        c->s0 = c->view.strides[0];
    } else if (ncomp == 3 && c->view.ndim == 2 && c->view.shape[1] == 3) {
        c->n = c->view.shape[0];
        c->s0 = c->view.strides[0];
        c->s1 = c->view.strides[1];
    } else if (ncomp == 3 && c->view.ndim == 1 && c->view.shape[0] % 3 == 0) {
        c->n = c->view.shape[0] / 3;
        c->s0 = 3 * c->view.strides[0];
        c->s1 = c->view.strides[0];
    } else {
        PyErr_Format(PyExc_ValueError, "%s must be %s, not %d-dimensional", name,
                     ncomp == 3 ? "of shape (n, 3) (or flat, 3n long)" : "one-dimensional",
                     c->view.ndim);
        col_release(c);
        return -1;
    }
    return 0;
}

static inline double col_f(const col *c, Py_ssize_t i, int k)
{
    const char *p = c->p + i * c->s0 + k * c->s1;
    switch (c->kind) {
    case COL_SCALAR: return c->f;
    case COL_F32: { float v; memcpy(&v, p, 4); return v; }
    case COL_F64: { double v; memcpy(&v, p, 8); return v; }
    default: return 0;
    }
}

/* face i as an int64 (signed and unsigned 64-bit values past INT64_MAX come out negative:
 * refused either way). */
static inline long long col_i(const col *c, Py_ssize_t i)
{
    const char *p = c->p + i * c->s0;
    if (c->kind == COL_SCALAR)
        return c->i;
    if (c->kind == COL_NONE)
        return 0;
    int s = c->kind == COL_INT;
    switch (c->isize) {
    case 1: return s ? (long long)*(const int8_t *)p : (long long)*(const uint8_t *)p;
    case 2: { uint16_t v; memcpy(&v, p, 2); return s ? (long long)(int16_t)v : (long long)v; }
    case 4: { uint32_t v; memcpy(&v, p, 4); return s ? (long long)(int32_t)v : (long long)v; }
    default: { int64_t v; memcpy(&v, p, 8); return (long long)v; }
    }
}

/* The common length of the columns (buffers must agree; numbers broadcast); 1 when every
 * column is a number. -1 with ValueError on a mismatch. */
static Py_ssize_t cols_len(col *cols, int ncols)
{
    Py_ssize_t n = -1;
    const char *first = NULL;
    for (int i = 0; i < ncols; i++) {
        if (cols[i].n < 0)
            continue;
        if (n < 0) {
            n = cols[i].n;
            first = cols[i].name;
        } else if (cols[i].n != n) {
            PyErr_Format(PyExc_ValueError, "%s has %zd queries but %s has %zd: the arrays must "
                         "have the same length", cols[i].name, cols[i].n, first, n);
            return -1;
        }
    }
    return n < 0 ? 1 : n;
}

/* ---- options ---------------------------------------------------------------------------------- */

#define NAME_STR_(NAME, str, value) " " str
static const char MODE_NAMES[] = STP_MODES(NAME_STR_);
static const char FILTER_NAMES[] = STP_FILTERS(NAME_STR_);
static const char ZERO_NAMES[] = STP_ZERO_RULES(NAME_STR_);
#undef NAME_STR_
#define NAME_STR4_(NAME, str, value, size) " " str
static const char FORMAT_NAMES[] = STP_OUTFMTS(NAME_STR4_);
#undef NAME_STR4_

typedef struct sopts {
    const char *mode, *filter, *format, *zero_rule, *nonfinite;
    PyObject   *max_aniso;        /* None or an int 0..255 */
    float       sharpness, width, blur;
    PyObject   *out;
    int         lerp;             /* sample(): Ptex's lerp option (SAMPLE flag bit 5) */
} sopts;

static int parse_one(const char *what, const char *v, int (*parse)(const char *),
                     const char *names, unsigned *out)
{
    int x = parse(v);
    if (x < 0) {
        PyErr_Format(PyExc_ValueError, "unknown %s '%s' (one of:%s)", what, v, names);
        return -1;
    }
    *out = (unsigned)x;
    return 0;
}

/* sopts -> stc_sample_opts; *pass_nonfinite 1 when NaN / infinity go to the server. */
static int opts_to_stc(const sopts *s, stc_sample_opts *o, int *pass_nonfinite)
{
    memset(o, 0, sizeof *o);
    if (parse_one("mode", s->mode, stp_mode_parse, MODE_NAMES, &o->mode) < 0 ||
        parse_one("filter", s->filter, stp_filter_parse, FILTER_NAMES, &o->filter) < 0 ||
        parse_one("format", s->format, stp_outfmt_parse, FORMAT_NAMES, &o->outfmt) < 0 ||
        parse_one("zero_rule", s->zero_rule, stp_zero_rule_parse, ZERO_NAMES, &o->zero_rule) < 0)
        return -1;
    if (!strcmp(s->nonfinite, "raise")) {
        *pass_nonfinite = 0;
    } else if (!strcmp(s->nonfinite, "status")) {
        *pass_nonfinite = 1;
    } else {
        PyErr_Format(PyExc_ValueError, "nonfinite='%s': 'raise' or 'status'", s->nonfinite);
        return -1;
    }
    unsigned aniso = 0;
    if (st_py_uint_arg(s->max_aniso, "max_aniso", 255, &aniso) < 0)
        return -1;
    o->max_aniso = aniso;
    o->sharpness = s->sharpness;
    o->width = s->width;
    o->blur = s->blur;
    o->want = STC_WANT_COVERAGE | STC_WANT_STATUS | (s->lerp ? STC_WANT_LERP : 0);
    return 0;
}

/* ---- the call -------------------------------------------------------------------------------- */

/* What the GIL-free part reports back. */
typedef struct job {
    int          rc;              /* stc code, or 0 */
    int          bad_col;         /* a column index with a bad value, or -1 */
    Py_ssize_t   bad_at;
    double       bad_val;         /* the bad float */
    long long    bad_face;        /* or the bad face id */
    int          oom;
    void        *vals;            /* malloc'd results (NULL when written to out) */
    float       *cov;
    uint8_t     *st;
    unsigned     nchan, outfmt;
    int          out_mismatch;    /* out's size does not fit n * nchan */
} job;

/* The item format of the values by stp_outfmt: libseamtex delivers f16 replies widened to
 * float (seamtex.h), so f16 values are "f" here, 4 bytes each. */
static const char *const OUT_FORMAT[] = {"f", "B", "H", "f"};
#define COUNT_OUTFMT_(NAME, str, v, size) +1
_Static_assert(sizeof OUT_FORMAT / sizeof OUT_FORMAT[0] == 0 STP_OUTFMTS(COUNT_OUTFMT_),
               "an item format for every output format");
#undef COUNT_OUTFMT_

/* Bytes of one value as the library delivers it. */
static size_t value_size(unsigned outfmt)
{
    return outfmt == STP_OUT_F16 ? sizeof(float) : stp_outfmt_size(outfmt);
}

/* Copies the connection-owned result into fresh arrays or into out. GIL released. */
static void take_result(job *j, const stc_sample_result *r, size_t n, Py_buffer *out)
{
    size_t esz = value_size(r->outfmt), vbytes = n * r->nchan * esz;
    if (r->count != n || esz == 0) {  /* stc_sample promises n results; never trust blindly */
        j->rc = STC_EPROTO;
        return;
    }
    j->nchan = r->nchan;
    j->outfmt = r->outfmt;
    if (out) {
        if ((size_t)out->len != vbytes) {
            j->out_mismatch = 1;
            return;
        }
    } else if (!(j->vals = malloc(vbytes ? vbytes : 1))) {
        j->oom = 1;
        return;
    }
    j->cov = malloc(n ? n * sizeof(float) : 1);
    j->st = malloc(n ? n : 1);
    if (!j->cov || !j->st) {
        j->oom = 1;
        return;
    }
    memcpy(out ? out->buf : j->vals, r->values, vbytes);
    if (r->coverage)
        memcpy(j->cov, r->coverage, n * sizeof(float));
    else
        for (size_t i = 0; i < n; i++)
            j->cov[i] = 1.0f;
    if (r->status)
        memcpy(j->st, r->status, n);
    else
        memset(j->st, 0, n);
}

/* Builds (values, coverage, status) after the call; frees what it does not hand on. */
static PyObject *finish(st_py_client *self, job *j, size_t n, PyObject *out_obj,
                        Py_buffer *out, col *cols, int ncols)
{
    PyObject *r = NULL;
    (void)ncols;
    if (j->bad_col >= 0) {
        if (j->bad_col > 0 || strcmp(cols[0].name, "face") != 0)
            PyErr_Format(PyExc_ValueError, "%s[%zd] is %s: queries must be finite (or pass "
                         "nonfinite='status' to get the server's per-query NONFINITE status)",
                         cols[j->bad_col].name, j->bad_at, isnan(j->bad_val) ? "NaN" : "infinite");
        else
            PyErr_Format(PyExc_ValueError, "%s[%zd] = %lld is not a face id 0..2^32-1",
                         cols[j->bad_col].name, j->bad_at, j->bad_face);
    } else if (j->rc) {
        st_py_client_fail(self, j->rc);
    } else if (j->oom) {
        PyErr_NoMemory();
    } else if (j->out_mismatch) {
        PyErr_Format(PyExc_ValueError, "out holds %zd bytes but %zu queries of %u channels of "
                     "format '%s' need %zu", out->len, n, j->nchan, OUT_FORMAT[j->outfmt],
                     n * j->nchan * value_size(j->outfmt));
    } else {
        PyObject *v, *c, *s;
        if (out_obj) {
            Py_INCREF(out_obj);
            v = out_obj;
        } else {
            v = st_py_array_wrap(j->vals, OUT_FORMAT[j->outfmt],
                                 (Py_ssize_t)value_size(j->outfmt), 2, (Py_ssize_t)n,
                                 j->nchan);
            j->vals = NULL;
        }
        c = st_py_array_wrap(j->cov, "f", 4, 1, (Py_ssize_t)n, 0);
        s = st_py_array_wrap(j->st, "B", 1, 1, (Py_ssize_t)n, 0);
        j->cov = NULL;
        j->st = NULL;
        v = v ? st_py_array_out(self, v) : NULL;
        c = c ? st_py_array_out(self, c) : NULL;
        s = s ? st_py_array_out(self, s) : NULL;
        if (v && c && s)
            r = PyTuple_Pack(3, v, c, s);
        Py_XDECREF(v);
        Py_XDECREF(c);
        Py_XDECREF(s);
    }
    free(j->vals);
    free(j->cov);
    free(j->st);
    return r;
}

/* The writable, C-contiguous buffer of out (values), its item format matching outfmt. */
static int out_get(PyObject *out_obj, unsigned outfmt, Py_buffer *out)
{
    if (PyObject_GetBuffer(out_obj, out, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0) {
        PyErr_Clear();
        PyErr_SetString(PyExc_TypeError, "out must be a writable, C-contiguous buffer "
                        "(a numpy array of shape (n, nchan))");
        return -1;
    }
    const char *f = out->format ? out->format : "B";
    if (*f == '@' || *f == '=' || *f == '<')
        f++;
    if (strcmp(f, OUT_FORMAT[outfmt]) != 0 &&
        !(outfmt == STP_OUT_UNORM8 && !strcmp(f, "b")) &&
        !(outfmt == STP_OUT_UNORM16 && !strcmp(f, "h"))) {
        PyErr_Format(PyExc_TypeError, "out has format '%s' but format='%s' returns '%s'",
                     out->format ? out->format : "B", stp_outfmt_name(outfmt),
                     OUT_FORMAT[outfmt]);
        PyBuffer_Release(out);
        return -1;
    }
    return 0;
}

#define SAMPLE_KW "mode", "filter", "format", "zero_rule", "max_aniso", "sharpness", "width", \
                  "blur", "nonfinite", "out"

/* ---- one call, shared by sample and sample_dir ------------------------------------------------ */

/* What a call holds between argument parsing and the reply: its columns, the query count, the
 * caller's out buffer. pack fills the n queries of the call's type (with the GIL released,
 * so it reads only the columns) and records the first bad value in j; send makes the
 * request. */
typedef struct call {
    st_py_client   *self;
    const char     *name;
    sopts           s;
    stc_sample_opts so;
    int             pass_nf;
    col             cols[7];
    int             ncols;        /* columns obtained (to release) */
    Py_ssize_t      n;
    Py_buffer       out;
    int             have_out;
    size_t          qsize;        /* bytes per query */
    void          (*pack)(const struct call *c, void *q, job *j);
    int           (*send)(const struct call *c, const void *q, stc_sample_result *res);
} call;

/* Takes the columns o[0..ncols) (named names[], is_int / ncomp each), checks their lengths
 * and takes the out buffer. On failure the exception is set and call_end releases what was
 * taken. */
static int call_begin(call *c, PyObject *const *o, const char *const *names, int ncols,
                      const int *is_int, const int *ncomp)
{
    for (; c->ncols < ncols; c->ncols++)
        if (col_get(o[c->ncols], names[c->ncols], is_int[c->ncols], ncomp[c->ncols],
                    &c->cols[c->ncols]) < 0)
            return -1;
    c->n = cols_len(c->cols, ncols);
    if (c->n < 0)
        return -1;
    if (c->s.out && c->s.out != Py_None) {
        if (out_get(c->s.out, c->so.outfmt, &c->out) < 0)
            return -1;
        c->have_out = 1;
    }
    return 0;
}

/* Packs, sends and reads the reply with the GIL released; returns the result tuple. */
static PyObject *call_run(call *c)
{
    st_py_client *self = c->self;
    if (st_py_client_enter(self) < 0)
        return NULL;
    job j;
    memset(&j, 0, sizeof j);
    j.bad_col = -1;
    size_t n = (size_t)c->n;
    Py_BEGIN_ALLOW_THREADS
    double t0 = st_py_now(), t1 = t0, t2 = t0;
    void *q = st_py_client_scratch(self, (n ? n : 1) * c->qsize);
    if (!q) {
        j.oom = 1;
    } else {
        c->pack(c, q, &j);
        if (j.bad_col < 0) {
            stc_sample_result res;
            t1 = st_py_now();
            j.rc = c->send(c, q, &res);
            t2 = st_py_now();
            if (!j.rc)
                take_result(&j, &res, n, c->have_out ? &c->out : NULL);
        }
    }
    self->times[0] = t1 - t0, self->times[1] = t2 - t1, self->times[2] = st_py_now() - t2;
    Py_END_ALLOW_THREADS
    PyObject *r = finish(self, &j, n, c->have_out ? c->s.out : NULL,
                         c->have_out ? &c->out : NULL, c->cols, c->ncols);
    st_py_client_leave(self);
    return r;
}

static void call_end(call *c)
{
    if (c->have_out)
        PyBuffer_Release(&c->out);
    for (int i = 0; i < c->ncols; i++)
        col_release(&c->cols[i]);
}

/* ---- sample --------------------------------------------------------------------------------------- */

static void pack_uv(const call *c, void *qv, job *j)
{
    stc_query *q = qv;
    for (Py_ssize_t i = 0; i < c->n && j->bad_col < 0; i++) {
        long long f = col_i(&c->cols[0], i);
        float fv[6];
        if (f < 0 || f > (long long)UINT32_MAX) {
            j->bad_col = 0, j->bad_at = i, j->bad_face = f;
            break;
        }
        q[i].face = (uint32_t)f;
        for (int k = 0; k < 6; k++) {
            fv[k] = (float)col_f(&c->cols[k + 1], i, 0);
            if (!c->pass_nf && !isfinite(fv[k])) {
                j->bad_col = k + 1, j->bad_at = i, j->bad_val = fv[k];
                break;
            }
        }
        q[i].u = fv[0], q[i].v = fv[1], q[i].dudx = fv[2], q[i].dvdx = fv[3];
        q[i].dudy = fv[4], q[i].dvdy = fv[5];
    }
}

static int send_uv(const call *c, const void *q, stc_sample_result *res)
{
    return stc_sample(c->self->conn, c->name, &c->so, q, (size_t)c->n, res);
}

#define SOPTS_DEFAULT {"traverse", "bilinear", "f32", "nan", "raise", NULL, 0, 0, 0, NULL, 0}

PyObject *st_py_sample(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"name", "face", "u", "v", "dudx", "dvdx", "dudy", "dvdy",
                             SAMPLE_KW, "lerp", NULL};
    static const char *const names[7] = {"face", "u", "v", "dudx", "dvdx", "dudy", "dvdy"};
    static const int is_int[7] = {1, 0, 0, 0, 0, 0, 0}, ncomp[7] = {1, 1, 1, 1, 1, 1, 1};
    PyObject *o[7] = {NULL, NULL, NULL, NULL, NULL, NULL, NULL};
    call c = {.self = self, .s = SOPTS_DEFAULT, .qsize = sizeof(stc_query),
              .pack = pack_uv, .send = send_uv};
    sopts *s = &c.s;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sOOO|OOOO$ssssOfffsOp:sample", kwlist, &c.name,
                                     &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &s->mode,
                                     &s->filter, &s->format, &s->zero_rule, &s->max_aniso,
                                     &s->sharpness, &s->width, &s->blur, &s->nonfinite, &s->out,
                                     &s->lerp))
        return NULL;
    if (opts_to_stc(s, &c.so, &c.pass_nf) < 0)
        return NULL;
    for (int i = 0; i < 3; i++)   /* None read as "not given" = 0: sample(name, None, u, v)
                                     used to sample face 0, a None u or v the edge 0 */
        if (o[i] == Py_None) {
            PyErr_Format(PyExc_TypeError, "%s must be %s or an object with the buffer protocol "
                         "(numpy array, array.array, memoryview), not None", names[i],
                         i ? "a number" : "an int");
            return NULL;
        }
    PyObject *r = call_begin(&c, o, names, 7, is_int, ncomp) < 0 ? NULL : call_run(&c);
    call_end(&c);
    return r;
}

/* ---- sample_dir ----------------------------------------------------------------------------------- */

static void pack_dir(const call *c, void *qv, job *j)
{
    stc_dir_query *q = qv;
    int cone = c->so.footprint;
    for (Py_ssize_t i = 0; i < c->n && j->bad_col < 0; i++) {
        for (int k = 0; k < 9 && j->bad_col < 0; k++) {
            int ci = k / 3;
            float v = (float)col_f(&c->cols[ci], i, k % 3);
            if (!c->pass_nf && !isfinite(v))
                j->bad_col = ci, j->bad_at = i, j->bad_val = v;
            (ci == 0 ? q[i].dir : ci == 1 ? q[i].ddx : q[i].ddy)[k % 3] = v;
        }
        if (cone) {
            float v = (float)col_f(&c->cols[3], i, 0);
            if (!c->pass_nf && !isfinite(v) && j->bad_col < 0)
                j->bad_col = 3, j->bad_at = i, j->bad_val = v;
            q[i].ddx[0] = v;
        }
    }
}

static int send_dir(const call *c, const void *q, stc_sample_result *res)
{
    return stc_sample_dir(c->self->conn, c->name, &c->so, q, (size_t)c->n, res);
}

PyObject *st_py_sample_dir(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"name", "dirs", "ddx", "ddy", "cone", SAMPLE_KW, NULL};
    static const char *const names[4] = {"dirs", "ddx", "ddy", "cone"};
    static const int is_int[4] = {0, 0, 0, 0}, ncomp[4] = {3, 3, 3, 1};
    PyObject *o[4] = {NULL, NULL, NULL, NULL};
    call c = {.self = self, .s = SOPTS_DEFAULT, .qsize = sizeof(stc_dir_query),
              .pack = pack_dir, .send = send_dir};
    sopts *s = &c.s;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sO|OOO$ssssOfffsO:sample_dir", kwlist, &c.name,
                                     &o[0], &o[1], &o[2], &o[3], &s->mode, &s->filter,
                                     &s->format, &s->zero_rule, &s->max_aniso, &s->sharpness,
                                     &s->width, &s->blur, &s->nonfinite, &s->out))
        return NULL;
    if (opts_to_stc(s, &c.so, &c.pass_nf) < 0)
        return NULL;
    int cone = o[3] && o[3] != Py_None;
    if (cone && ((o[1] && o[1] != Py_None) || (o[2] && o[2] != Py_None))) {
        PyErr_SetString(PyExc_ValueError, "give either cone or ddx / ddy, not both");
        return NULL;
    }
    c.so.footprint = cone ? 1 : 0;
    PyObject *r = NULL;
    if (call_begin(&c, o, names, 4, is_int, ncomp) == 0) {
        if (c.cols[0].kind == COL_NONE)
            PyErr_SetString(PyExc_TypeError, "dirs is required");
        else
            r = call_run(&c);
    }
    call_end(&c);
    return r;
}

const char st_py_sample_doc[] =
"sample(name, face, u, v, dudx=None, dvdx=None, dudy=None, dvdy=None, *,\n"
"       mode='traverse', filter='bilinear', format='f32', zero_rule='nan', max_aniso=0,\n"
"       sharpness=0.0, width=0.0, blur=0.0, nonfinite='raise', out=None, lerp=False)\n"
"       -> (values, coverage, status)\n\n"
"Samples set name at n points in one round trip (split and pipelined by libseamtex when n\n"
"exceeds the server's batch limit). face, u, v and the derivatives are 1-D arrays with the\n"
"buffer protocol (numpy, array.array, memoryview) of equal length, or numbers broadcast to\n"
"every query (derivatives default to 0). face: any integer type, 0..2^32-1; the rest float32\n"
"or float64 (sent as float32).\n\n"
"mode: 'discard', 'traverse', 'clamp'. filter: 'point', 'bilinear', 'trilinear', 'aniso',\n"
"'ptex-point' ... 'ptex-mitchell'. format: 'f32' (float32 values), 'unorm8' (uint8),\n"
"'unorm16' (uint16). zero_rule: 'nan' or 'clamp' (Discard with no tap inside).\n"
"sharpness (0..1, ptex-bicubic), width (0..1e4, 0 = 1), blur (0..1e4): Ptex's filter options;\n"
"lerp=True: Ptex's lerp option (ptex-gaussian and the bicubic family blend toward the next\n"
"lower resolution; a server before session 26 refuses it with Invalid).\n"
"nonfinite: 'raise' (ValueError on NaN / infinity in any input) or 'status' (sent as is;\n"
"the server reports NONFINITE for that query).\n\n"
"Returns values[n, nchan], coverage[n] (float32) and status[n] (uint8: 0 OK, 1 BAD_FACE,\n"
"2 NONFINITE, 3 BAD_FOOTPRINT, 4 ZERO_COVERAGE; seamtex.QSTATUS names them): numpy arrays\n"
"when numpy is used (Client(numpy=...)), else seamtex.Array. out: a writable C-contiguous\n"
"array of n * nchan items of the format's type to receive the values (returned as values).\n"
"The GIL is released while the queries are packed, sent and answered.\n"
"Raises NotFound, Invalid, TooLarge, ... (seamtex.Error) for a refused request; TypeError /\n"
"ValueError for bad arguments.";

const char st_py_sample_dir_doc[] =
"sample_dir(name, dirs, ddx=None, ddy=None, cone=None, *, mode='traverse',\n"
"           filter='bilinear', format='f32', zero_rule='nan', max_aniso=0, sharpness=0.0,\n"
"           width=0.0, blur=0.0, nonfinite='raise', out=None) -> (values, coverage, status)\n\n"
"Samples a cube set by direction. dirs: float32/float64 array of shape (n, 3) (or flat, 3n\n"
"long). Footprint: ddx and ddy (shape (n, 3): the direction's screen derivatives), or cone\n"
"(the full cone angle in radians: one number, or an array of n). Other arguments and the\n"
"result as in sample().";
