/* Compiled simulator kernel: the IMU model's Gauss-Markov block filter and its per-sample output,
 * and the guidance law's control loops, operation for operation the Python references in sim/imu.py
 * (first_order_filter_python, imu_output_python) and sim/guidance.py (law_python). Loaded through
 * sim/kernel.py; docs/development.md, "Compiled kernels".
 *
 * Bit identity with CPython (and, for the filter, with scipy.signal.lfilter, which the reference
 * reproduces) is the contract, so, as in fusion/_strapdown.c:
 * - every expression keeps the Python's evaluation order and parenthesisation, each operation
 *   rounded to double;
 * - built with -ffp-contract=off (no fused multiply-add), never -ffast-math or -march=native
 *   (setup.py);
 * - Python's errors are reproduced where the reference raises them: round() of an infinite or
 *   NaN quotient raises OverflowError / ValueError with CPython's messages, in the reference's
 *   order;
 * - only exact floats in exact tuples / lists (and float64 buffers for the filter) take this
 *   path: anything else (ints, numpy scalars, other sequences, keyword arguments, wrong lengths,
 *   other dtypes, overlapping input and output) calls the bound Python reference, which then
 *   raises or computes exactly as it always did. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

static PyObject *filter_ref = NULL; /* sim.imu.first_order_filter_python */
static PyObject *output_ref = NULL; /* sim.imu.imu_output_python */
static PyObject *law_ref = NULL;    /* sim.guidance.law_python */
static PyObject *controls_type = NULL; /* sim.guidance.Controls */

/* physconst.G0_MPS2 and sim.guidance's _PI, _TWO_PI, _RAD_3: the Python module's floats,
 * handed over once by bind_guidance() */
static double G0_MPS2, PI, TWO_PI, RAD_3;

#define MAX_COLUMNS 64

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

/* Values of a tuple (a NamedTuple included) of exactly n exact floats; 0 if it is not one. */
static int
floats_of_any_tuple(PyObject *seq, double *out, Py_ssize_t n)
{
    if (!PyTuple_Check(seq) || PyTuple_GET_SIZE(seq) != n) {
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

/* Length of an exact tuple or list, or -1. */
static Py_ssize_t
seq_len(PyObject *seq)
{
    if (PyTuple_CheckExact(seq)) {
        return PyTuple_GET_SIZE(seq);
    }
    if (PyList_CheckExact(seq)) {
        return PyList_GET_SIZE(seq);
    }
    return -1;
}

static int
is_float64_2d(const Py_buffer *b)
{
    return b->ndim == 2 && b->itemsize == 8 && b->format != NULL
           && (strcmp(b->format, "d") == 0 || strcmp(b->format, "=d") == 0
               || strcmp(b->format, "@d") == 0);
}

/* The bytes [lo, hi) that a 2-D buffer touches. */
static void
span(const Py_buffer *b, char **lo, char **hi)
{
    char *a = (char *)b->buf, *z = (char *)b->buf;
    for (int d = 0; d < 2; d++) {
        Py_ssize_t ext = (b->shape[d] - 1) * b->strides[d];
        if (ext < 0) {
            a += ext;
        }
        else {
            z += ext;
        }
    }
    *lo = a;
    *hi = z + b->itemsize;
}

PyDoc_STRVAR(first_order_filter_doc,
"first_order_filter(x, b0, a1, zi, out)\n--\n\n"
"scipy.signal.lfilter([b0[j]], [1.0, a1[j]], x[:, j], zi=[zi[j]])[0] into out[:, j]:\n"
":func:`sim.imu.first_order_filter_python`, bit for bit.");

static PyObject *
first_order_filter(PyObject *module, PyObject *const *args, Py_ssize_t nargsf,
                   PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double b[MAX_COLUMNS], a[MAX_COLUMNS], z[MAX_COLUMNS];
    Py_buffer xb, ob;
    int have_x = 0, have_o = 0, ok = 0;
    Py_ssize_t k = -1;
    if (filter_ref == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "sim._simkernel.bind_imu() was not called");
        return NULL;
    }
    if (kwnames == NULL && nargs == 5) {
        k = seq_len(args[3]);
    }
    if (k >= 1 && k <= MAX_COLUMNS && floats_of(args[1], b, k) && floats_of(args[2], a, k)
        && floats_of(args[3], z, k)) {
        if (PyObject_GetBuffer(args[0], &xb, PyBUF_STRIDES | PyBUF_FORMAT) == 0) {
            have_x = 1;
        }
        else {
            PyErr_Clear();
        }
        if (have_x
            && PyObject_GetBuffer(args[4], &ob, PyBUF_STRIDES | PyBUF_FORMAT | PyBUF_WRITABLE)
                   == 0) {
            have_o = 1;
        }
        else {
            PyErr_Clear();
        }
        if (have_o && is_float64_2d(&xb) && is_float64_2d(&ob) && xb.shape[1] == k
            && ob.shape[1] == k && xb.shape[0] == ob.shape[0]) {
            ok = 1;
            if (xb.shape[0] > 0) {
                char *xl, *xh, *ol, *oh;
                span(&xb, &xl, &xh);
                span(&ob, &ol, &oh);
                /* the reference reads all of x before it writes: the same elements in place are
                 * fine, any other overlap goes to it */
                if (xl < oh && ol < xh
                    && !(xb.buf == ob.buf && xb.strides[0] == ob.strides[0]
                         && xb.strides[1] == ob.strides[1])) {
                    ok = 0;
                }
            }
        }
    }
    if (!ok) {
        if (have_o) {
            PyBuffer_Release(&ob);
        }
        if (have_x) {
            PyBuffer_Release(&xb);
        }
        return PyObject_Vectorcall(filter_ref, args, nargsf, kwnames);
    }
    const Py_ssize_t n = xb.shape[0];
    for (Py_ssize_t i = 0; i < n; i++) {
        const char *xr = (const char *)xb.buf + i * xb.strides[0];
        char *orow = (char *)ob.buf + i * ob.strides[0];
        for (Py_ssize_t j = 0; j < k; j++) {
            const double xv = *(const double *)(xr + j * xb.strides[1]);
            const double y = z[j] + b[j] * xv;
            z[j] = xv * 0.0 - y * a[j];
            *(double *)(orow + j * ob.strides[1]) = y;
        }
    }
    PyBuffer_Release(&ob);
    PyBuffer_Release(&xb);
    Py_RETURN_NONE;
}

/* round(v / q) * q as CPython computes it: float.__round__ (round half to even, through
 * PyLong_FromDouble, so an infinite or NaN quotient raises and a zero is +0.0), then
 * int * float. */
static int
quantise(double *v, double q)
{
    const double x = *v / q;
    double rounded = round(x);
    if (fabs(x - rounded) == 0.5) {
        rounded = 2.0 * round(x / 2.0);
    }
    if (isinf(rounded)) {
        PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
        return -1;
    }
    if (isnan(rounded)) {
        PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
        return -1;
    }
    if (rounded == 0.0) {
        rounded = 0.0; /* the int 0 has no sign */
    }
    *v = rounded * q;
    return 0;
}

static double
saturate(double y, double r)
{
    return y > r ? r : y < -r ? -r : y;
}

PyDoc_STRVAR(imu_output_doc,
"imu_output(u, e, p)\n--\n\n"
"One IMU output: :func:`sim.imu.imu_output_python`, bit for bit.");

static PyObject *
imu_output(PyObject *module, PyObject *const *args, Py_ssize_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double u[6], e[6], p[22], y[6];
    if (output_ref == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "sim._simkernel.bind_imu() was not called");
        return NULL;
    }
    if (kwnames != NULL || nargs != 3 || !floats_of(args[0], u, 6) || !floats_of(args[1], e, 6)
        || !floats_of(args[2], p, 22)) {
        return PyObject_Vectorcall(output_ref, args, nargsf, kwnames);
    }
    const double *ta = p, *tg = p + 9;
    y[0] = ta[0] * u[0] + ta[1] * u[1] + ta[2] * u[2] + e[0];
    y[1] = ta[3] * u[0] + ta[4] * u[1] + ta[5] * u[2] + e[1];
    y[2] = ta[6] * u[0] + ta[7] * u[1] + ta[8] * u[2] + e[2];
    y[3] = tg[0] * u[3] + tg[1] * u[4] + tg[2] * u[5] + e[3];
    y[4] = tg[3] * u[3] + tg[4] * u[4] + tg[5] * u[5] + e[4];
    y[5] = tg[6] * u[3] + tg[7] * u[4] + tg[8] * u[5] + e[5];
    for (int i = 0; i < 6; i++) {
        y[i] = saturate(y[i], i < 3 ? p[18] : p[19]);
    }
    for (int t = 0; t < 2; t++) {
        const double q = p[20 + t];
        if (q > 0.0) {
            for (int i = 3 * t; i < 3 * t + 3; i++) {
                if (quantise(&y[i], q) < 0) {
                    return NULL;
                }
            }
        }
    }
    PyObject *out = PyList_New(6);
    if (out == NULL) {
        return NULL;
    }
    for (int i = 0; i < 6; i++) {
        PyObject *f = PyFloat_FromDouble(y[i]);
        if (f == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, i, f);
    }
    return out;
}

PyDoc_STRVAR(bind_imu_doc,
"bind_imu(first_order_filter_ref, imu_output_ref)\n--\n\n"
"The Python references the kernel calls for inputs it does not take (sim.kernel does this).");

static PyObject *
bind_imu(PyObject *module, PyObject *args)
{
    PyObject *f, *o;
    if (!PyArg_ParseTuple(args, "OO:bind_imu", &f, &o)) {
        return NULL;
    }
    if (!PyCallable_Check(f) || !PyCallable_Check(o)) {
        PyErr_SetString(PyExc_TypeError, "bind_imu: the references must be callable");
        return NULL;
    }
    Py_INCREF(f);
    Py_INCREF(o);
    Py_XSETREF(filter_ref, f);
    Py_XSETREF(output_ref, o);
    Py_RETURN_NONE;
}


/* math.sin / math.tan / math.cos / math.asin as CPython's math_1 does them: a NaN result from a
 * non-NaN argument is a domain error (these never overflow for finite arguments here). */
#define PY_MATH(out, func, arg)                                                             \
    do {                                                                                    \
        double x_ = (arg);                                                                  \
        (out) = func(x_);                                                                   \
        if (isnan(out) && !isnan(x_)) {                                                     \
            PyErr_SetString(PyExc_ValueError, "math domain error");                         \
            goto error;                                                                     \
        }                                                                                   \
    } while (0)

/* a % b for floats as CPython's float_rem (b != 0 here: 2 pi) */
static double
py_mod(double a, double b)
{
    double mod = fmod(a, b);
    if (mod) {
        if ((b < 0) != (mod < 0)) {
            mod += b;
        }
    }
    else {
        mod = copysign(0.0, b);
    }
    return mod;
}

/* Python's max(a, b) / min(a, b) for two floats: the first unless the second compares greater
 * (smaller) */
static double
py_max(double a, double b)
{
    return b > a ? b : a;
}

static double
py_min(double a, double b)
{
    return b < a ? b : a;
}

/* Python's truth of bool / int 0-1 objects only; -1 if it is neither */
static int
exact_bool(PyObject *o)
{
    if (o == Py_True) {
        return 1;
    }
    if (o == Py_False) {
        return 0;
    }
    return -1;
}

static int
set_floats(PyObject *list, const double *v, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *f = PyFloat_FromDouble(v[i]);
        if (f == NULL) {
            return -1;
        }
        PyList_SetItem(list, i, f); /* steals f, drops the old item */
    }
    return 0;
}

PyDoc_STRVAR(law_doc,
"law(s, course_err, phi_fixed, limit, pitch_direct, theta_fixed, alt_target_m,\n"
"    airspeed_target_mps, climb_rate_mps, integrators, params)\n--\n\n"
"The guidance law's control loops: :func:`sim.guidance.law_python`, bit for bit.");

static PyObject *
law(PyObject *module, PyObject *const *args, Py_ssize_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double s[18], pr[29], in[5], course_err = 0.0;
    int have_course = 0, pitch_direct = -1;
    if (law_ref == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "sim._simkernel.bind_guidance() was not called");
        return NULL;
    }
    if (kwnames == NULL && nargs == 11) {
        pitch_direct = exact_bool(args[4]);
        if (args[1] != Py_None) {
            have_course = 1;
            if (PyFloat_CheckExact(args[1])) {
                course_err = PyFloat_AS_DOUBLE(args[1]);
            }
            else {
                pitch_direct = -1;
            }
        }
    }
    if (pitch_direct < 0 || !PyTuple_Check(args[0]) || !floats_of_any_tuple(args[0], s, 18)
        || !PyFloat_CheckExact(args[2]) || !PyFloat_CheckExact(args[3])
        || !PyFloat_CheckExact(args[5]) || !PyFloat_CheckExact(args[6])
        || !PyFloat_CheckExact(args[7]) || !PyFloat_CheckExact(args[8])
        || !PyList_CheckExact(args[9]) || !floats_of(args[9], in, 5)
        || !floats_of(args[10], pr, 29)) {
        return PyObject_Vectorcall(law_ref, args, nargsf, kwnames);
    }
    const double phi_fixed = PyFloat_AS_DOUBLE(args[2]), limit = PyFloat_AS_DOUBLE(args[3]);
    const double theta_fixed = PyFloat_AS_DOUBLE(args[5]);
    const double alt_target = PyFloat_AS_DOUBLE(args[6]);
    const double airspeed_target = PyFloat_AS_DOUBLE(args[7]);
    const double climb_rate = PyFloat_AS_DOUBLE(args[8]);
    const double k_course = pr[0], k_alt = pr[1], k_hdot = pr[2], ki_hdot = pr[3],
                 pitch_min = pr[4], pitch_max = pr[5], alpha_max = pr[6], k_alpha = pr[7],
                 speed_guard = pr[8], k_speed_guard = pr[9], k_phi = pr[10], ki_phi = pr[11],
                 k_p = pr[12], k_theta = pr[13], max_q = pr[14], k_q = pr[15],
                 ki_theta = pr[16], k_beta = pr[17], ki_beta = pr[18], k_r = pr[19],
                 k_v = pr[20], ki_v = pr[21], trim_phi = pr[22], trim_theta = pr[23],
                 trim_qbar = pr[24], trim_ail = pr[25], trim_ele = pr[26], trim_rud = pr[27],
                 trim_thr = pr[28];
    const double dt = s[1], alt = s[4], v_down = s[7], airspeed = s[8], phi = s[9],
                 theta = s[10], p = s[12], q = s[13], r = s[14], alpha = s[15], beta = s[16],
                 qbar = s[17];
    double x, protect, phi_cmd, theta_cmd;
    const double v = 1.0 > airspeed ? 1.0 : airspeed;
    const double alpha_margin = alpha_max - alpha;
    if (pitch_direct) {
        protect = 0.0;
    }
    else {
        x = 1.0 - alpha_margin / RAD_3;
        protect = x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x;
    }
    if (!have_course) {
        phi_cmd = phi_fixed;
    }
    else {
        x = atan(v * k_course * course_err / G0_MPS2);
        phi_cmd = x < -limit ? -limit : x > limit ? limit : x;
        phi_cmd += trim_phi;
    }
    phi_cmd *= 1.0 - 0.5 * protect;

    const double hdot = -v_down;
    const double speed_err = airspeed_target - airspeed;
    if (pitch_direct) {
        theta_cmd = theta_fixed;
    }
    else {
        const double climb = climb_rate;
        x = k_alt * (alt_target - alt);
        const double hdot_cmd = x < -climb ? -climb : x > climb ? climb : x;
        const double hdot_err = hdot_cmd - hdot;
        x = hdot_cmd / v;
        double gamma_ff;
        PY_MATH(gamma_ff, asin, x < -0.5 ? -0.5 : x > 0.5 ? 0.5 : x);
        double theta_unsat = trim_theta + gamma_ff + k_hdot * hdot_err + in[0];
        const double under = py_max(0.0, speed_err - speed_guard);
        const double over = py_max(0.0, -speed_err - 2.0 * speed_guard);
        theta_unsat += k_speed_guard * (over - under);
        theta_cmd = theta_unsat < pitch_min ? pitch_min
                    : theta_unsat > pitch_max ? pitch_max
                                              : theta_unsat;
        if (protect == 0.0
            && (theta_cmd == theta_unsat || (theta_cmd > theta_unsat) == (hdot_err > 0.0))) {
            in[0] += ki_hdot * hdot_err * dt;
        }
    }

    x = trim_qbar / (1.0 > qbar ? 1.0 : qbar);
    const double sched = x < 0.5 ? 0.5 : x > 2.0 ? 2.0 : x;

    const double phi_err = py_mod(phi_cmd - phi + PI, TWO_PI) - PI;
    const double aileron_unsat = trim_ail + sched * (k_phi * phi_err - k_p * p) + in[1];
    const double aileron = aileron_unsat < -1.0  ? -1.0
                           : aileron_unsat > 1.0 ? 1.0
                                                 : aileron_unsat;
    if (aileron == aileron_unsat) {
        in[1] += sched * ki_phi * phi_err * dt;
    }

    double sin_phi, tan_phi_c, cos_theta;
    PY_MATH(sin_phi, sin, phi);
    const double phi_c = phi < -1.2 ? -1.2 : phi > 1.2 ? 1.2 : phi;
    PY_MATH(tan_phi_c, tan, phi_c);
    const double q_turn = G0_MPS2 / v * sin_phi * tan_phi_c;
    const double theta_err = theta_cmd - theta;
    x = k_theta * theta_err;
    double q_cmd = (x < -max_q ? -max_q : x > max_q ? max_q : x) + q_turn;
    if (!pitch_direct && alpha_margin < 0.0) {
        q_cmd = py_min(q_cmd, k_alpha * alpha_margin);
    }
    const double pull = sched * k_q * (q_cmd - q) + in[2];
    const double elevator_unsat = trim_ele - pull;
    const double elevator = elevator_unsat < -1.0  ? -1.0
                            : elevator_unsat > 1.0 ? 1.0
                                                   : elevator_unsat;
    if (elevator == elevator_unsat && (protect == 0.0 || theta_err < 0.0)) {
        in[2] += sched * ki_theta * theta_err * dt;
    }

    PY_MATH(cos_theta, cos, theta);
    const double r_turn = G0_MPS2 / v * sin_phi * cos_theta;
    const double rudder_unsat = trim_rud - sched * (k_beta * beta - k_r * (r - r_turn)) + in[3];
    const double rudder = rudder_unsat < -1.0  ? -1.0
                          : rudder_unsat > 1.0 ? 1.0
                                               : rudder_unsat;
    if (rudder == rudder_unsat) {
        in[3] -= sched * ki_beta * beta * dt;
    }

    const double throttle_unsat = trim_thr + k_v * speed_err + in[4];
    const double throttle = throttle_unsat < 0.0  ? 0.0
                            : throttle_unsat > 1.0 ? 1.0
                                                   : throttle_unsat;
    if (throttle == throttle_unsat || (throttle > throttle_unsat) == (speed_err > 0.0)) {
        in[4] += ki_v * speed_err * dt;
    }
    if (set_floats(args[9], in, 5) < 0) {
        return NULL;
    }
    {
        PyObject *c[4] = {PyFloat_FromDouble(aileron), PyFloat_FromDouble(elevator),
                          PyFloat_FromDouble(rudder), PyFloat_FromDouble(throttle)};
        PyObject *res = NULL;
        if (c[0] != NULL && c[1] != NULL && c[2] != NULL && c[3] != NULL) {
            res = PyObject_Vectorcall(controls_type, c, 4, NULL);
        }
        for (int i = 0; i < 4; i++) {
            Py_XDECREF(c[i]);
        }
        return res;
    }
error:
    /* the reference has updated the integrators it reached before raising */
    if (set_floats(args[9], in, 5) < 0) {
        return NULL;
    }
    return NULL;
}

PyDoc_STRVAR(bind_guidance_doc,
"bind_guidance(law_ref, controls_type, constants)\n--\n\n"
"The guidance law's Python reference (the fallback) and its result type (sim.kernel does this).");

static PyObject *
bind_guidance(PyObject *module, PyObject *args)
{
    PyObject *f, *t, *consts;
    double c[4];
    if (!PyArg_ParseTuple(args, "OOO:bind_guidance", &f, &t, &consts)) {
        return NULL;
    }
    if (!PyCallable_Check(f) || !PyCallable_Check(t)) {
        PyErr_SetString(PyExc_TypeError, "bind_guidance: the reference and type must be callable");
        return NULL;
    }
    if (!floats_of(consts, c, 4)) {
        PyErr_SetString(PyExc_TypeError, "bind_guidance: four float constants expected");
        return NULL;
    }
    G0_MPS2 = c[0];
    PI = c[1];
    TWO_PI = c[2];
    RAD_3 = c[3];
    Py_INCREF(f);
    Py_INCREF(t);
    Py_XSETREF(law_ref, f);
    Py_XSETREF(controls_type, t);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"first_order_filter", (PyCFunction)(void (*)(void))first_order_filter,
     METH_FASTCALL | METH_KEYWORDS, first_order_filter_doc},
    {"imu_output", (PyCFunction)(void (*)(void))imu_output, METH_FASTCALL | METH_KEYWORDS,
     imu_output_doc},
    {"bind_imu", bind_imu, METH_VARARGS, bind_imu_doc},
    {"law", (PyCFunction)(void (*)(void))law, METH_FASTCALL | METH_KEYWORDS, law_doc},
    {"bind_guidance", bind_guidance, METH_VARARGS, bind_guidance_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    "sim._simkernel",
    "Compiled simulator kernel, bit for bit the Python references in sim.imu.",
    -1,
    methods,
};

PyMODINIT_FUNC
PyInit__simkernel(void)
{
    return PyModule_Create(&module_def);
}
