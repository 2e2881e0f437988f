/* Compiled parts of the covariance time update, operation for operation their Python references
 * in fusion.error_model:
 * - transition_fill: the variable entries of the first-order transition Phi = I + F T
 *   (ErrorModel._fill), written straight into Phi (what ErrorModel.first_order_transition does
 *   with the reference's list through struct.pack_into and ndarray.put);
 * - add_process_noise: P += Q and the air-data block's noise and gust decay, element by element
 *   (ErrorModel.add_process_noise; numpy's in-place add and multiply round each element on its
 *   own, so a loop in the same order gives the same bits).
 *
 * Bit identity with CPython is the contract, the discipline of fusion/_strapdown.c:
 * - every expression keeps the Python's evaluation order and parenthesisation (C and Python
 *   both evaluate a * b + c as (a * b) + c, left to right, each operation rounded to double;
 *   a unary minus binds tighter than * and / in both);
 * - built with -ffp-contract=off (no fused multiply-add), never -ffast-math or -march=native
 *   (setup.py); no libm calls at all here (the Earth terms and the gravity gradient come in
 *   as the Python computed them);
 * - where the reference would raise (a zero divisor: ZeroDivisionError) or compute with other
 *   types (ints, numpy scalars, other sequences), this kernel writes nothing and returns False:
 *   the caller then runs the reference, which raises or computes exactly as it always did. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static PyTypeObject *terms_type = NULL; /* fusion.earth.LocalTerms */
static double RATE;                     /* fusion.earth.RATE */
static int bound = 0;

#define N_BASE 59  /* entries of every layout */
#define N_SCALE 18 /* -C_nb diag(f_b), -C_nb diag(omega_b) */
#define N_MISALIGN 36
#define N_MAX (N_BASE + N_SCALE + N_MISALIGN)

/* Values of an exact tuple (or an instance of exactly `type`, a tuple subclass) of exactly n
 * exact floats into out; 0 if it is not one. */
static int
floats_of(PyObject *seq, double *out, Py_ssize_t n, PyTypeObject *type)
{
    if (!(PyTuple_CheckExact(seq) || (type != NULL && Py_IS_TYPE(seq, type)))) {
        return 0;
    }
    if (PyTuple_GET_SIZE(seq) != n) {
        return 0;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *item = PyTuple_GET_ITEM(seq, i);
        if (!PyFloat_CheckExact(item)) {
            return 0;
        }
        out[i] = PyFloat_AS_DOUBLE(item);
    }
    return 1;
}

static int
float_of(PyObject *o, double *out)
{
    if (!PyFloat_CheckExact(o)) {
        return 0;
    }
    *out = PyFloat_AS_DOUBLE(o);
    return 1;
}

/* num / den, or leave to the reference (which raises ZeroDivisionError) on a zero divisor */
#define DIV(out, num, den)                                                                  \
    do {                                                                                    \
        double n_ = (num);                                                                  \
        double d_ = (den);                                                                  \
        if (d_ == 0.0) {                                                                    \
            return 0;                                                                       \
        }                                                                                   \
        (out) = n_ / d_;                                                                    \
    } while (0)

/* ErrorModel._fill, line for line; returns the number of values written to vals, 0 where the
 * reference would raise. t = (rho_n, rho_e, g, sin_lat, cos_lat). */
static int
fill(double *vals, const double *t, double dg_dlat, double dg_dh, const double *v,
     const double *c_nb, const double *f_n, const double *f_b, const double *w_b, double k,
     double one, int scale, int misalign)
{
    double rn = t[0], re = t[1], s = t[3], c = t[4];
    double tan, sec2;
    DIV(tan, s, c);
    DIV(sec2, 1.0, c * c);
    double vn = v[0], ve = v[1], vd = v[2];
    double fn = f_n[0], fe = f_n[1], fd = f_n[2];
    double om = RATE;
    double wie_n = om * c, wie_d = -om * s;
    double wen_n, wen_e, wen_d;
    DIV(wen_n, ve, re);
    DIV(wen_e, -vn, rn);
    DIV(wen_d, -ve * tan, re);
    double die_n0, die_d0, den_d0;
    DIV(die_n0, -om * s, rn);
    DIV(die_d0, -om * c, rn);
    DIV(den_d0, -ve * sec2, re * rn);
    double den_n2, den_e2, den_d2;
    DIV(den_n2, ve, re * re);
    DIV(den_e2, -vn, rn * rn);
    DIV(den_d2, -ve * tan, re * re);
    double w_n0 = 2.0 * die_n0, w_e0 = 0.0, w_d0 = 2.0 * die_d0 + den_d0;
    double w_n2 = den_n2, w_e2 = den_e2, w_d2 = den_d2;
    double fvr_00 = ve * w_d0 - vd * w_e0;
    double fvr_10 = vd * w_n0 - vn * w_d0;
    double dg_rn;
    DIV(dg_rn, dg_dlat, rn);
    double fvr_20 = vn * w_e0 - ve * w_n0 + dg_rn;
    double fvr_02 = ve * w_d2 - vd * w_e2;
    double fvr_12 = vd * w_n2 - vn * w_d2;
    double fvr_22 = vn * w_e2 - ve * w_n2 - dg_dh;
    double cx = 2.0 * wie_n + wen_n, cy = wen_e, cz = 2.0 * wie_d + wen_d;
    double a01, a10, a21;
    DIV(a01, 1.0, re);
    DIV(a10, -1.0, rn);
    DIV(a21, -tan, re);
    double fvv_00 = -vd * a10, fvv_01 = ve * a21 + cz, fvv_02 = -cy;
    double fvv_10 = -cz, fvv_11 = vd * a01 - vn * a21, fvv_12 = cx;
    double fvv_20 = vn * a10 + cy, fvv_21 = -ve * a01 - cx, fvv_22 = 0.0;
    double m = -k;
    double c00 = m * c_nb[0], c01 = m * c_nb[1], c02 = m * c_nb[2];
    double c10 = m * c_nb[3], c11 = m * c_nb[4], c12 = m * c_nb[5];
    double c20 = m * c_nb[6], c21 = m * c_nb[7], c22 = m * c_nb[8];
    fn = k * fn;
    fe = k * fe;
    fd = k * fd;
    double win_n = k * (wie_n + wen_n), win_e = k * wen_e, win_d = k * (wie_d + wen_d);
    a01 = k * a01;
    a10 = k * a10;
    a21 = k * a21;
    /* the reference's F_rr entries, each with its own divisions */
    double r0, r1, r2, r3a, r3b, r4;
    DIV(r0, -vd, rn);
    DIV(r1, vn, rn);
    DIV(r2, ve * tan, rn);
    DIV(r3a, vd, re);
    DIV(r3b, vn * tan, rn);
    DIV(r4, ve, re);
    double *o = vals;
    /* F_rr */
    *o++ = r0 * k + one;
    *o++ = r1 * k;
    *o++ = r2 * k;
    *o++ = -(r3a + r3b) * k + one;
    *o++ = r4 * k;
    /* F_vr (cols 0, 2) */
    *o++ = fvr_00 * k;
    *o++ = fvr_02 * k;
    *o++ = fvr_10 * k;
    *o++ = fvr_12 * k;
    *o++ = fvr_20 * k;
    *o++ = fvr_22 * k;
    /* F_vv */
    *o++ = fvv_00 * k + one;
    *o++ = fvv_01 * k;
    *o++ = fvv_02 * k;
    *o++ = fvv_10 * k;
    *o++ = fvv_11 * k + one;
    *o++ = fvv_12 * k;
    *o++ = fvv_20 * k;
    *o++ = fvv_21 * k;
    *o++ = fvv_22 * k + one;
    /* F_vphi = -[f_n x] */
    *o++ = fd;
    *o++ = -fe;
    *o++ = -fd;
    *o++ = fn;
    *o++ = fe;
    *o++ = -fn;
    /* F_v,ba = -C_nb */
    *o++ = c00;
    *o++ = c01;
    *o++ = c02;
    *o++ = c10;
    *o++ = c11;
    *o++ = c12;
    *o++ = c20;
    *o++ = c21;
    *o++ = c22;
    /* F_phi,r = -(N_ie + N_en) (cols 0, 2) */
    *o++ = -die_n0 * k;
    *o++ = -den_n2 * k;
    *o++ = 0.0;
    *o++ = -den_e2 * k;
    *o++ = -(die_d0 + den_d0) * k;
    *o++ = -den_d2 * k;
    /* F_phi,v = -N_env */
    *o++ = -a01;
    *o++ = -a10;
    *o++ = -a21;
    /* F_phi,phi = -[omega_in x] */
    *o++ = win_d;
    *o++ = -win_e;
    *o++ = -win_d;
    *o++ = win_n;
    *o++ = win_e;
    *o++ = -win_n;
    /* F_phi,bg = -C_nb */
    *o++ = c00;
    *o++ = c01;
    *o++ = c02;
    *o++ = c10;
    *o++ = c11;
    *o++ = c12;
    *o++ = c20;
    *o++ = c21;
    *o++ = c22;
    if (scale) {
        double fx = f_b[0], fy = f_b[1], fz = f_b[2];
        *o++ = c00 * fx;
        *o++ = c01 * fy;
        *o++ = c02 * fz;
        *o++ = c10 * fx;
        *o++ = c11 * fy;
        *o++ = c12 * fz;
        *o++ = c20 * fx;
        *o++ = c21 * fy;
        *o++ = c22 * fz;
        double wx = w_b[0], wy = w_b[1], wz = w_b[2];
        *o++ = c00 * wx;
        *o++ = c01 * wy;
        *o++ = c02 * wz;
        *o++ = c10 * wx;
        *o++ = c11 * wy;
        *o++ = c12 * wz;
        *o++ = c20 * wx;
        *o++ = c21 * wy;
        *o++ = c22 * wz;
    }
    if (misalign) {
        const double *xyz[2] = {f_b, w_b};
        for (int i = 0; i < 2; i++) {
            double x = xyz[i][0], y = xyz[i][1], z = xyz[i][2];
            *o++ = c00 * y;
            *o++ = c00 * z;
            *o++ = c01 * x;
            *o++ = c01 * z;
            *o++ = c02 * x;
            *o++ = c02 * y;
            *o++ = c10 * y;
            *o++ = c10 * z;
            *o++ = c11 * x;
            *o++ = c11 * z;
            *o++ = c12 * x;
            *o++ = c12 * y;
            *o++ = c20 * y;
            *o++ = c20 * z;
            *o++ = c21 * x;
            *o++ = c21 * z;
            *o++ = c22 * x;
            *o++ = c22 * y;
        }
    }
    return (int)(o - vals);
}

PyDoc_STRVAR(transition_fill_doc,
"transition_fill(phi, index, terms, dg, v_ned_mps, c_nb, f_n_mps2, f_b_mps2, omega_ib_b_rps,\n"
"                k, one, scale, misalignment) -> bool\n\n"
"Write ErrorModel._fill's values (``k F + one I``'s variable entries) into the flat\n"
"entries ``index`` of ``phi`` (C-contiguous float64, writable; ``index`` intp). False, with\n"
"nothing written, where the reference would raise or take another path (non-float inputs).");

static PyObject *
transition_fill(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (!bound) {
        PyErr_SetString(PyExc_RuntimeError, "fusion._update.bind() was not called");
        return NULL;
    }
    if (nargs != 13) {
        PyErr_SetString(PyExc_TypeError, "transition_fill takes 13 positional arguments");
        return NULL;
    }
    double t[5], dg[2], v[3], c_nb[9], f_n[3], f_b[3], w_b[3], k, one;
    if (!(floats_of(args[2], t, 5, terms_type) && floats_of(args[3], dg, 2, NULL)
          && floats_of(args[4], v, 3, NULL) && floats_of(args[5], c_nb, 9, NULL)
          && floats_of(args[6], f_n, 3, NULL) && floats_of(args[7], f_b, 3, NULL)
          && floats_of(args[8], w_b, 3, NULL) && float_of(args[9], &k)
          && float_of(args[10], &one))) {
        Py_RETURN_FALSE;
    }
    int scale = PyObject_IsTrue(args[11]);
    int misalign = PyObject_IsTrue(args[12]);
    if (scale < 0 || misalign < 0) {
        return NULL;
    }
    double vals[N_MAX];
    int n = fill(vals, t, dg[0], dg[1], v, c_nb, f_n, f_b, w_b, k, one, scale, misalign);
    if (n == 0) {
        Py_RETURN_FALSE;
    }
    Py_buffer phi, idx;
    if (PyObject_GetBuffer(args[0], &phi, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT)
        < 0) {
        return NULL;
    }
    if (PyObject_GetBuffer(args[1], &idx, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyBuffer_Release(&phi);
        return NULL;
    }
    PyObject *result = NULL;
    Py_ssize_t size = phi.len / (Py_ssize_t)sizeof(double);
    if (phi.itemsize != (Py_ssize_t)sizeof(double) || strcmp(phi.format, "d") != 0) {
        PyErr_SetString(PyExc_TypeError, "phi must be a float64 array");
        goto done;
    }
    if (idx.itemsize != (Py_ssize_t)sizeof(Py_ssize_t)
        || idx.len != n * (Py_ssize_t)sizeof(Py_ssize_t)) {
        PyErr_SetString(PyExc_ValueError, "index must hold one intp per variable entry");
        goto done;
    }
    const Py_ssize_t *ix = (const Py_ssize_t *)idx.buf;
    for (int i = 0; i < n; i++) {
        if (ix[i] < 0 || ix[i] >= size) {
            PyErr_SetString(PyExc_IndexError, "index out of bounds for phi");
            goto done;
        }
    }
    double *p = (double *)phi.buf;
    for (int i = 0; i < n; i++) {
        p[ix[i]] = vals[i];
    }
    result = Py_True;
    Py_INCREF(result);
done:
    PyBuffer_Release(&idx);
    PyBuffer_Release(&phi);
    return result;
}

/* A C-contiguous, writable (if asked) 2-D float64 n x n buffer of obj, or 0 with no error set. */
static int
square_f64(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t *n)
{
    int flags = PyBUF_ND | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Clear();
        return 0;
    }
    if (view->ndim != 2 || view->shape[0] != view->shape[1] || view->itemsize != 8
        || strcmp(view->format, "d") != 0) {
        PyBuffer_Release(view);
        return 0;
    }
    *n = view->shape[0];
    return 1;
}

PyDoc_STRVAR(add_process_noise_doc,
"add_process_noise(P, Q, air, q_wind, q_scale, gust_phi, q_gust) -> bool\n\n"
"ErrorModel.add_process_noise's reference in place, element by element in its order:\n"
"``P += Q``; with ``air >= 0`` (the air block's offset) ``P[a, a] += q_wind``,\n"
"``P[a+1, a+1] += q_wind``, ``P[a+2, a+2] += q_scale``, rows then columns ``g, g+1``\n"
"(``g = a + 3``) times ``gust_phi``, ``P[g, g] += q_gust``, ``P[g+1, g+1] += q_gust``.\n"
"False, with nothing changed, for anything the reference would treat otherwise (not two\n"
"n x n C-contiguous float64 arrays, P read-only, non-float scalars, air block outside P).");

static PyObject *
add_process_noise(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "add_process_noise takes 7 positional arguments");
        return NULL;
    }
    double q_wind, q_scale, gust_phi, q_gust;
    if (!(PyLong_CheckExact(args[2]) && float_of(args[3], &q_wind) && float_of(args[4], &q_scale)
          && float_of(args[5], &gust_phi) && float_of(args[6], &q_gust))) {
        Py_RETURN_FALSE;
    }
    Py_ssize_t a = PyLong_AsSsize_t(args[2]);
    if (a == -1 && PyErr_Occurred()) {
        PyErr_Clear();
        Py_RETURN_FALSE;
    }
    Py_buffer pv, qv;
    Py_ssize_t n, nq;
    if (!square_f64(args[0], &pv, 1, &n)) {
        Py_RETURN_FALSE;
    }
    if (!square_f64(args[1], &qv, 0, &nq)) {
        PyBuffer_Release(&pv);
        Py_RETURN_FALSE;
    }
    int ok = nq == n && a >= -1 && a + 4 < n && pv.buf != qv.buf;
    if (ok) {
        double *P = (double *)pv.buf;
        const double *Q = (const double *)qv.buf;
        Py_ssize_t nn = n * n;
        /* P += Q */
        for (Py_ssize_t i = 0; i < nn; i++) {
            P[i] += Q[i];
        }
        if (a >= 0) {
            Py_ssize_t g = a + 3;
            P[a * n + a] += q_wind;
            P[(a + 1) * n + a + 1] += q_wind;
            P[(a + 2) * n + a + 2] += q_scale;
            /* P[g : g + 2, :] *= phi */
            for (Py_ssize_t i = g; i < g + 2; i++) {
                for (Py_ssize_t j = 0; j < n; j++) {
                    P[i * n + j] *= gust_phi;
                }
            }
            /* P[:, g : g + 2] *= phi */
            for (Py_ssize_t i = 0; i < n; i++) {
                P[i * n + g] *= gust_phi;
                P[i * n + g + 1] *= gust_phi;
            }
            P[g * n + g] += q_gust;
            P[(g + 1) * n + g + 1] += q_gust;
        }
    }
    PyBuffer_Release(&qv);
    PyBuffer_Release(&pv);
    if (ok) {
        Py_RETURN_TRUE;
    }
    Py_RETURN_FALSE;
}

PyDoc_STRVAR(bind_doc, "bind(local_terms_type, earth_rate): the Earth model's type and constant.");

static PyObject *
bind(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *type;
    double rate;
    if (!PyArg_ParseTuple(args, "O!d", &PyType_Type, &type, &rate)) {
        return NULL;
    }
    Py_XDECREF(terms_type);
    Py_INCREF(type);
    terms_type = (PyTypeObject *)type;
    RATE = rate;
    bound = 1;
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"transition_fill", (PyCFunction)(void (*)(void))transition_fill, METH_FASTCALL,
     transition_fill_doc},
    {"add_process_noise", (PyCFunction)(void (*)(void))add_process_noise, METH_FASTCALL,
     add_process_noise_doc},
    {"bind", bind, METH_VARARGS, bind_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    "fusion._update",
    "Compiled part of the covariance time update, bit for bit fusion.error_model's reference.",
    -1,
    methods,
};

PyMODINIT_FUNC
PyInit__update(void)
{
    return PyModule_Create(&module_def);
}
