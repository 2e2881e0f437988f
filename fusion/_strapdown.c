/* Compiled INS mechanisation: fusion.strapdown.update and the increment helpers, operation for
 * operation the Python reference in fusion/strapdown.py (update_python, increments_python, ...).
 *
 * Bit identity with CPython is the contract, so:
 * - every expression keeps the Python's evaluation order and parenthesisation (C and Python
 *   both evaluate a * b + c as (a * b) + c, left to right, each operation rounded to double);
 * - built with -ffp-contract=off (no fused multiply-add), never -ffast-math or -march=native
 *   (setup.py);
 * - sin and cos are the libm functions CPython's math module calls (-fno-builtin-sin/-cos: gcc
 *   would otherwise merge sin(x) and cos(x) into one sincos() call, whose bits libm does not
 *   promise to match); sqrt is correctly rounded by IEEE 754 wherever it comes from;
 * - Python's errors are reproduced where the reference raises them: ZeroDivisionError for a
 *   zero divisor, ValueError("math domain error") for sin/cos/sqrt of a value that gives NaN
 *   from a non-NaN argument (sin(inf)), checked in the reference's order;
 * - the Earth constants are the Python module's floats, handed over once by bind();
 * - only exact floats in exact tuples / lists take this path: anything else (ints, numpy
 *   scalars, other sequences, keyword arguments, wrong lengths) calls the Python reference,
 *   which then raises or computes exactly as it always did. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

static PyTypeObject *ins_type = NULL;   /* fusion.strapdown.InsState */
static PyObject *update_ref = NULL;     /* fusion.strapdown.update_python */
static PyObject *increments_ref = NULL;
static PyObject *increments_scaled_ref = NULL;
static PyObject *increments_compensated_ref = NULL;

/* Earth-model constants (fusion.strapdown's module globals) */
static double E2, A, ONE_MINUS_E2, GE, KS, GH1, GH1S, GH2, RATE, TWELFTH;

/* Values of an exact tuple or list of exactly n exact floats into out; 0 if it is not one. */
static int
floats_of(PyObject *seq, double *out, Py_ssize_t n)
{
    PyObject **items;
    if (PyTuple_CheckExact(seq)) {
        if (PyTuple_GET_SIZE(seq) != n) {
            return 0;
        }
        items = &PyTuple_GET_ITEM(seq, 0);
    }
    else if (PyList_CheckExact(seq)) {
        if (PyList_GET_SIZE(seq) != n) {
            return 0;
        }
        items = ((PyListObject *)seq)->ob_item;
    }
    else {
        return 0;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!PyFloat_CheckExact(items[i])) {
            return 0;
        }
        out[i] = PyFloat_AS_DOUBLE(items[i]);
    }
    return 1;
}

/* math.sin / math.cos / math.sqrt as CPython's math_1 does them (a NaN result from a non-NaN
 * argument is a domain error; these three never overflow). */
static int
domain_error(void)
{
    PyErr_SetString(PyExc_ValueError, "math domain error");
    return -1;
}

#define PY_MATH(out, func, arg)                                                             \
    do {                                                                                    \
        double x_ = (arg);                                                                  \
        (out) = func(x_);                                                                   \
        if (isnan(out) && !isnan(x_)) {                                                     \
            domain_error();                                                                 \
            goto error;                                                                     \
        }                                                                                   \
    } while (0)

/* num / den as CPython's float division: a zero divisor raises ZeroDivisionError. */
#define PY_DIV(out, num, den)                                                               \
    do {                                                                                    \
        double n_ = (num);                                                                  \
        double d_ = (den);                                                                  \
        if (d_ == 0.0) {                                                                    \
            PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");             \
            goto error;                                                                     \
        }                                                                                   \
        (out) = n_ / d_;                                                                    \
    } while (0)

static PyObject *
float_tuple(const double *v, Py_ssize_t n)
{
    PyObject *t = PyTuple_New(n);
    if (t == NULL) {
        return NULL;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *f = PyFloat_FromDouble(v[i]);
        if (f == NULL) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, i, f);
    }
    return t;
}

/* InsState(lat, lon, h, v, q) as the reference's tuple.__new__(InsState, (...)) */
static PyObject *
new_state(double lat, double lon, double h, const double *v, const double *q)
{
    PyObject *items[5] = {PyFloat_FromDouble(lat), PyFloat_FromDouble(lon),
                          PyFloat_FromDouble(h), float_tuple(v, 3), float_tuple(q, 4)};
    PyObject *r = NULL;
    for (int i = 0; i < 5; i++) {
        if (items[i] == NULL) {
            goto done;
        }
    }
#if PY_VERSION_HEX < 0x030E0000
    /* what tuple.__new__ does for a tuple subclass (Objects/tupleobject.c, tuple_subtype_new) */
    r = ins_type->tp_alloc(ins_type, 5);
    if (r != NULL) {
        for (int i = 0; i < 5; i++) {
            PyTuple_SET_ITEM(r, i, items[i]);
            items[i] = NULL;
        }
    }
#else
    {
        PyObject *t = PyTuple_New(5);
        if (t != NULL) {
            for (int i = 0; i < 5; i++) {
                PyTuple_SET_ITEM(t, i, items[i]);
                items[i] = NULL;
            }
            PyObject *args = PyTuple_Pack(1, t);
            Py_DECREF(t);
            if (args != NULL) {
                r = PyTuple_Type.tp_new(ins_type, args, NULL);
                Py_DECREF(args);
            }
        }
    }
#endif
done:
    for (int i = 0; i < 5; i++) {
        Py_XDECREF(items[i]);
    }
    return r;
}

/* The state's five fields if it is an InsState or an exact tuple of exact floats and float
 * tuples / lists of the right lengths. */
static int
state_of(PyObject *state, double *llh, double *v, double *q)
{
    if (Py_TYPE(state) != ins_type && !PyTuple_CheckExact(state)) {
        return 0;
    }
    if (PyTuple_GET_SIZE(state) != 5) {
        return 0;
    }
    for (int i = 0; i < 3; i++) {
        PyObject *f = PyTuple_GET_ITEM(state, i);
        if (!PyFloat_CheckExact(f)) {
            return 0;
        }
        llh[i] = PyFloat_AS_DOUBLE(f);
    }
    return floats_of(PyTuple_GET_ITEM(state, 3), v, 3)
           && floats_of(PyTuple_GET_ITEM(state, 4), q, 4);
}

PyDoc_STRVAR(update_doc,
"update(state, dtheta_b, dv_b, dtheta_prev_b, dv_prev_b, dt_s)\n--\n\n"
"Advance the INS over one IMU interval: the compiled form of\n"
":func:`fusion.strapdown.update_python`, bit for bit (see that function and this\n"
"module's source).");

static PyObject *
update(PyObject *module, PyObject *const *args, Py_ssize_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double llh[3], v[3], q[4], th[3], u[3], pth[3], pu[3];
    if (ins_type == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "fusion._strapdown.bind() was not called");
        return NULL;
    }
    if (kwnames != NULL || nargs != 6 || !PyFloat_CheckExact(args[5])
        || !state_of(args[0], llh, v, q) || !floats_of(args[1], th, 3)
        || !floats_of(args[2], u, 3) || !floats_of(args[3], pth, 3)
        || !floats_of(args[4], pu, 3)) {
        return PyObject_Vectorcall(update_ref, args, nargsf, kwnames);
    }
    const double dt_s = PyFloat_AS_DOUBLE(args[5]);
    const double lat = llh[0], lon = llh[1], h = llh[2];
    const double vn = v[0], ve = v[1], vd = v[2];
    const double qw = q[0], qx = q[1], qy = q[2], qz = q[3];
    const double ax = th[0], ay = th[1], az = th[2];
    const double ux = u[0], uy = u[1], uz = u[2];
    const double pax = pth[0], pay = pth[1], paz = pth[2];
    const double pux = pu[0], puy = pu[1], puz = pu[2];
    double s_lat, c_lat, root, r_n, rho_n, g, tan_lat, wen_n, wen_e, wen_d, a, bw, k, nw, norm;
    double dlat, lon_step;

    /* Earth terms at mid-interval height */
    const double h_mid = h - 0.5 * vd * dt_s;
    PY_MATH(s_lat, sin, lat);
    PY_MATH(c_lat, cos, lat);
    const double sin2 = s_lat * s_lat;
    const double x = 1.0 - E2 * sin2;
    PY_MATH(root, sqrt, x);
    PY_DIV(r_n, A, root);
    const double rho_e = r_n + h_mid;
    PY_DIV(rho_n, r_n * ONE_MINUS_E2, x);
    rho_n = rho_n + h_mid;
    PY_DIV(g, GE * (1.0 + KS * sin2), root);
    g = g * (1.0 - (GH1 - GH1S * sin2) * h_mid + GH2 * h_mid * h_mid);
    PY_DIV(tan_lat, s_lat, c_lat);
    const double wie_n = RATE * c_lat;
    const double wie_d = -RATE * s_lat;

    /* rotation and sculling */
    const double wx = ux + 0.5 * (ay * uz - az * uy)
                      + (pay * uz - paz * uy + puy * az - puz * ay) * TWELFTH;
    const double wy = uy + 0.5 * (az * ux - ax * uz)
                      + (paz * ux - pax * uz + puz * ax - pux * az) * TWELFTH;
    const double wz = uz + 0.5 * (ax * uy - ay * ux)
                      + (pax * uy - pay * ux + pux * ay - puy * ax) * TWELFTH;
    double tx = 2.0 * (qy * wz - qz * wy);
    double ty = 2.0 * (qz * wx - qx * wz);
    double tz = 2.0 * (qx * wy - qy * wx);
    const double dn = wx + qw * tx + qy * tz - qz * ty;
    const double de = wy + qw * ty + qz * tx - qx * tz;
    const double dd = wz + qw * tz + qx * ty - qy * tx;
    const double mvn = vn + 0.5 * dn;
    const double mve = ve + 0.5 * de;
    const double mvd = vd + 0.5 * (dd + g * dt_s);
    PY_DIV(wen_n, mve, rho_e);
    PY_DIV(wen_e, -mvn, rho_n);
    PY_DIV(wen_d, -mve * tan_lat, rho_e);

    /* 1. attitude: coning, q_b = q(phi) */
    const double phx = ax + (pay * az - paz * ay) * TWELFTH;
    const double phy = ay + (paz * ax - pax * az) * TWELFTH;
    const double phz = az + (pax * ay - pay * ax) * TWELFTH;
    double a2 = phx * phx + phy * phy + phz * phz;
    if (a2 < 1e-4) {
        bw = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
        k = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;
    }
    else {
        double s;
        PY_MATH(a, sqrt, a2);
        PY_MATH(bw, cos, 0.5 * a);
        PY_MATH(s, sin, 0.5 * a);
        PY_DIV(k, s, a);
    }
    const double bx = k * phx, by = k * phy, bz = k * phz;
    /* q_n = q(-zeta) */
    const double zx = (wie_n + wen_n) * dt_s;
    const double zy = wen_e * dt_s;
    const double zz = (wie_d + wen_d) * dt_s;
    a2 = zx * zx + zy * zy + zz * zz;
    if (a2 < 1e-4) {
        nw = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
        k = a2 / 48.0 - 0.5 - a2 * a2 / 3840.0;
    }
    else {
        double s;
        PY_MATH(a, sqrt, a2);
        PY_MATH(nw, cos, 0.5 * a);
        PY_MATH(s, sin, 0.5 * a);
        PY_DIV(k, -s, a);
    }
    const double nx = k * zx, ny = k * zy, nz = k * zz;
    /* t = q_nb (x) q_b */
    const double tw = qw * bw - qx * bx - qy * by - qz * bz;
    tx = qw * bx + qx * bw + qy * bz - qz * by;
    ty = qw * by - qx * bz + qy * bw + qz * bx;
    tz = qw * bz + qx * by - qy * bx + qz * bw;
    /* q_new = q_n (x) t */
    const double rw = nw * tw - nx * tx - ny * ty - nz * tz;
    const double rx = nw * tx + nx * tw + ny * tz - nz * ty;
    const double ry = nw * ty - nx * tz + ny * tw + nz * tx;
    const double rz = nw * tz + nx * ty - ny * tx + nz * tw;
    PY_MATH(norm, sqrt, rw * rw + rx * rx + ry * ry + rz * rz);
    if (rw < 0.0) {
        norm = -norm;
    }

    /* 2. velocity */
    const double cx = 2.0 * wie_n + wen_n;
    const double cz = 2.0 * wie_d + wen_d;
    double v_new[3];
    v_new[0] = vn + dn - 0.5 * (zy * dd - zz * de) - (wen_e * mvd - cz * mve) * dt_s;
    v_new[1] = ve + de - 0.5 * (zz * dn - zx * dd) - (cz * mvn - cx * mvd) * dt_s;
    v_new[2] = vd + dd - 0.5 * (zx * de - zy * dn) + (g - (cx * mve - wen_e * mvn)) * dt_s;

    /* 3. position */
    const double h_new = h - 0.5 * (vd + v_new[2]) * dt_s;
    const double dh_avg = 0.5 * (h + h_new) - h_mid;
    PY_DIV(dlat, 0.5 * (vn + v_new[0]) * dt_s, rho_n + dh_avg);
    const double c_mid = c_lat - 0.5 * s_lat * dlat;
    PY_DIV(lon_step, 0.5 * (ve + v_new[1]) * dt_s, (rho_e + dh_avg) * c_mid);
    double q_new[4];
    PY_DIV(q_new[0], rw, norm);
    PY_DIV(q_new[1], rx, norm);
    PY_DIV(q_new[2], ry, norm);
    PY_DIV(q_new[3], rz, norm);
    return new_state(lat + dlat, lon + lon_step, h_new, v_new, q_new);
error:
    return NULL;
}

/* ((a, b, c), (d, e, f)) */
static PyObject *
two_triples(const double *th, const double *dv)
{
    PyObject *a = float_tuple(th, 3);
    if (a == NULL) {
        return NULL;
    }
    PyObject *b = float_tuple(dv, 3);
    if (b == NULL) {
        Py_DECREF(a);
        return NULL;
    }
    PyObject *r = PyTuple_New(2);
    if (r == NULL) {
        Py_DECREF(a);
        Py_DECREF(b);
        return NULL;
    }
    PyTuple_SET_ITEM(r, 0, a);
    PyTuple_SET_ITEM(r, 1, b);
    return r;
}

PyDoc_STRVAR(increments_doc,
"increments(fw, dt_s, accel_bias_b_mps2, gyro_bias_b_rps)\n--\n\n"
"Compiled :func:`fusion.strapdown.increments_python`, bit for bit.");

static PyObject *
increments(PyObject *module, PyObject *const *args, Py_ssize_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double fw[6], ba[3], bg[3], th[3], dv[3];
    if (kwnames != NULL || nargs != 4 || !PyFloat_CheckExact(args[1])
        || !floats_of(args[0], fw, 6) || !floats_of(args[2], ba, 3)
        || !floats_of(args[3], bg, 3)) {
        return PyObject_Vectorcall(increments_ref, args, nargsf, kwnames);
    }
    const double dt = PyFloat_AS_DOUBLE(args[1]);
    for (int i = 0; i < 3; i++) {
        th[i] = (fw[3 + i] - bg[i]) * dt;
        dv[i] = (fw[i] - ba[i]) * dt;
    }
    return two_triples(th, dv);
}

PyDoc_STRVAR(increments_scaled_doc,
"increments_scaled(fw, dt_s, accel_bias_b_mps2, gyro_bias_b_rps, accel_scale_b, "
"gyro_scale_b)\n--\n\n"
"Compiled :func:`fusion.strapdown.increments_scaled_python`, bit for bit.");

static PyObject *
increments_scaled(PyObject *module, PyObject *const *args, Py_ssize_t nargsf,
                  PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double fw[6], ba[3], bg[3], sa[3], sg[3], th[3], dv[3];
    if (kwnames != NULL || nargs != 6 || !PyFloat_CheckExact(args[1])
        || !floats_of(args[0], fw, 6) || !floats_of(args[2], ba, 3)
        || !floats_of(args[3], bg, 3) || !floats_of(args[4], sa, 3)
        || !floats_of(args[5], sg, 3)) {
        return PyObject_Vectorcall(increments_scaled_ref, args, nargsf, kwnames);
    }
    const double dt = PyFloat_AS_DOUBLE(args[1]);
    /* the reference's order: the three gyro terms, then the three accelerometer terms */
    for (int i = 0; i < 3; i++) {
        PY_DIV(th[i], fw[3 + i] - bg[i], 1.0 + sg[i]);
        th[i] = th[i] * dt;
    }
    for (int i = 0; i < 3; i++) {
        PY_DIV(dv[i], fw[i] - ba[i], 1.0 + sa[i]);
        dv[i] = dv[i] * dt;
    }
    return two_triples(th, dv);
error:
    return NULL;
}

PyDoc_STRVAR(increments_compensated_doc,
"increments_compensated(fw, dt_s, accel_bias_b_mps2, gyro_bias_b_rps, accel_inverse, "
"gyro_inverse)\n--\n\n"
"Compiled :func:`fusion.strapdown.increments_compensated_python`, bit for bit.");

static PyObject *
increments_compensated(PyObject *module, PyObject *const *args, Py_ssize_t nargsf,
                       PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double fw[6], ba[3], bg[3], ai[9], gi[9], w[3], f[3], th[3], dv[3];
    if (kwnames != NULL || nargs != 6 || !PyFloat_CheckExact(args[1])
        || !floats_of(args[0], fw, 6) || !floats_of(args[2], ba, 3)
        || !floats_of(args[3], bg, 3) || !floats_of(args[4], ai, 9)
        || !floats_of(args[5], gi, 9)) {
        return PyObject_Vectorcall(increments_compensated_ref, args, nargsf, kwnames);
    }
    const double dt = PyFloat_AS_DOUBLE(args[1]);
    for (int i = 0; i < 3; i++) {
        w[i] = (fw[3 + i] - bg[i]) * dt;
        f[i] = (fw[i] - ba[i]) * dt;
    }
    for (int i = 0; i < 3; i++) {
        th[i] = gi[3 * i] * w[0] + gi[3 * i + 1] * w[1] + gi[3 * i + 2] * w[2];
        dv[i] = ai[3 * i] * f[0] + ai[3 * i + 1] * f[1] + ai[3 * i + 2] * f[2];
    }
    return two_triples(th, dv);
}

PyDoc_STRVAR(bind_doc,
"bind(ins_state_type, references, constants)\n--\n\n"
"Hand the kernel the InsState type, the Python reference functions (update, increments,\n"
"increments_scaled, increments_compensated: the fallback for inputs the kernel does not\n"
"take) and the Earth constants (E2, A, 1 - E2, GE, K_SOMIGLIANA, GH1, GH1S, GH2, RATE, 1/12)\n"
"as fusion.strapdown computed them. Called once by fusion.strapdown at import.");

static PyObject *
bind(PyObject *module, PyObject *args)
{
    PyObject *type, *refs, *consts;
    double c[10];
    if (!PyArg_ParseTuple(args, "O!O!O!:bind", &PyType_Type, &type, &PyTuple_Type, &refs,
                          &PyTuple_Type, &consts)) {
        return NULL;
    }
    if (!PyType_IsSubtype((PyTypeObject *)type, &PyTuple_Type)) {
        PyErr_SetString(PyExc_TypeError, "bind: the state type must be a tuple subclass");
        return NULL;
    }
    if (PyTuple_GET_SIZE(refs) != 4) {
        PyErr_SetString(PyExc_TypeError, "bind: four reference functions expected");
        return NULL;
    }
    for (int i = 0; i < 4; i++) {
        if (!PyCallable_Check(PyTuple_GET_ITEM(refs, i))) {
            PyErr_SetString(PyExc_TypeError, "bind: the references must be callable");
            return NULL;
        }
    }
    if (!floats_of(consts, c, 10)) {
        PyErr_SetString(PyExc_TypeError, "bind: ten float constants expected");
        return NULL;
    }
    Py_INCREF(type);
    Py_XSETREF(ins_type, (PyTypeObject *)type);
    PyObject **slots[4] = {&update_ref, &increments_ref, &increments_scaled_ref,
                           &increments_compensated_ref};
    for (int i = 0; i < 4; i++) {
        PyObject *f = PyTuple_GET_ITEM(refs, i);
        Py_INCREF(f);
        Py_XSETREF(*slots[i], f);
    }
    E2 = c[0];
    A = c[1];
    ONE_MINUS_E2 = c[2];
    GE = c[3];
    KS = c[4];
    GH1 = c[5];
    GH1S = c[6];
    GH2 = c[7];
    RATE = c[8];
    TWELFTH = c[9];
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"update", (PyCFunction)(void (*)(void))update, METH_FASTCALL | METH_KEYWORDS, update_doc},
    {"increments", (PyCFunction)(void (*)(void))increments, METH_FASTCALL | METH_KEYWORDS,
     increments_doc},
    {"increments_scaled", (PyCFunction)(void (*)(void))increments_scaled,
     METH_FASTCALL | METH_KEYWORDS, increments_scaled_doc},
    {"increments_compensated", (PyCFunction)(void (*)(void))increments_compensated,
     METH_FASTCALL | METH_KEYWORDS, increments_compensated_doc},
    {"bind", bind, METH_VARARGS, bind_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    "fusion._strapdown",
    "Compiled INS mechanisation, bit for bit the Python reference in fusion.strapdown.",
    -1,
    methods,
};

PyMODINIT_FUNC
PyInit__strapdown(void)
{
    return PyModule_Create(&module_def);
}
