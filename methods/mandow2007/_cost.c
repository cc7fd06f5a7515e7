/* Mandow 2007 eq. (13), the GA's cost J(K), in C: a second implementation of
 * methods.mandow2007.segments.segment_cost (the numpy one is the reference; tests/methods/mandow2007/
 * test_cost_c.py checks the two agree to 1e-12 relative and that the GA picks the same chromosomes).
 *
 * For each parameter row K = (x_ICRl, x_ICRr, y_ICRv, alpha_l, alpha_r) and each segment: eqs. (6)-(7)
 * integrated exactly over the segment's intervals (SE(2) exponential, zero-order hold), in the frame of the
 * segment start, compared with the reference increment; J = sum of squared position and wrapped heading
 * residuals.  The same per-interval arithmetic as segments._increments_chunk; the heading within a segment
 * starts at 1 instead of dividing the run's running heading by its value at the segment start, and sums run
 * in order: the last bits differ from numpy's (pairwise sums, running product over the whole run).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#define SMALL_ANGLE 0.05

static int get_buf(PyObject *o, Py_buffer *b, const char *fmt, const char *what) {
    if (PyObject_GetBuffer(o, b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return -1;
    if (b->ndim > 2 || strcmp(b->format, fmt) != 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected a contiguous array of format '%s', got '%s'", what, fmt, b->format);
        PyBuffer_Release(b);
        return -1;
    }
    return 0;
}

/* Python's float %: the result takes the sign of the divisor (numpy's remainder) */
static inline double wrap_angle(double a) {
    const double two_pi = 2 * M_PI;
    double x = a + M_PI;
    double mod = fmod(x, two_pi);
    if (mod != 0.0) {
        if (mod < 0) mod += two_pi;
    } else {
        mod = 0.0;
    }
    return mod - M_PI;
}

/* segment_cost(k (P*5), dl (M), dr (M), first (N, int64), ref_dx, ref_dy, ref_dphi (N), out (P)) */
static PyObject *segment_cost(PyObject *self, PyObject *args) {
    PyObject *ok_, *odl, *odr, *ofirst, *odx, *ody, *odphi, *oout;
    if (!PyArg_ParseTuple(args, "OOOOOOOO", &ok_, &odl, &odr, &ofirst, &odx, &ody, &odphi, &oout)) return NULL;
    Py_buffer bk, bdl, bdr, bfirst, bdx, bdy, bdphi, bout;
    int got = 0;
    PyObject *ret = NULL;
    if (get_buf(ok_, &bk, "d", "k") < 0) goto done;
    got = 1;
    if (get_buf(odl, &bdl, "d", "dl") < 0) goto done;
    got = 2;
    if (get_buf(odr, &bdr, "d", "dr") < 0) goto done;
    got = 3;
    if (get_buf(ofirst, &bfirst, "q", "first") < 0 && (PyErr_Clear(), get_buf(ofirst, &bfirst, "l", "first") < 0)) goto done;
    got = 4;
    if (get_buf(odx, &bdx, "d", "ref_dx") < 0) goto done;
    got = 5;
    if (get_buf(ody, &bdy, "d", "ref_dy") < 0) goto done;
    got = 6;
    if (get_buf(odphi, &bdphi, "d", "ref_dphi") < 0) goto done;
    got = 7;
    if (PyObject_GetBuffer(oout, &bout, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0) goto done;
    got = 8;
    {
        Py_ssize_t m = bdl.len / (Py_ssize_t)sizeof(double), n = bfirst.len / (Py_ssize_t)sizeof(int64_t);
        Py_ssize_t p = bout.len / (Py_ssize_t)sizeof(double);
        if (bdr.len != bdl.len || bk.len != p * 5 * (Py_ssize_t)sizeof(double) ||
            bdx.len != n * (Py_ssize_t)sizeof(double) || bdy.len != bdx.len || bdphi.len != bdx.len ||
            strcmp(bout.format, "d") != 0) {
            PyErr_SetString(PyExc_ValueError, "segment_cost: inconsistent array sizes");
            goto done;
        }
        const double *k = bk.buf, *dl = bdl.buf, *dr = bdr.buf, *rdx = bdx.buf, *rdy = bdy.buf, *rdphi = bdphi.buf;
        const int64_t *first = bfirst.buf;
        double *out = bout.buf;
        for (Py_ssize_t i = 1; i < n; i++) {
            if (first[i] <= first[i - 1] || first[i] >= m) {
                PyErr_SetString(PyExc_ValueError, "segment_cost: segment starts must strictly increase within the intervals");
                goto done;
            }
        }
        if (n && (first[0] != 0 || first[n - 1] >= m)) {
            PyErr_SetString(PyExc_ValueError, "segment_cost: the first segment must start at interval 0");
            goto done;
        }
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t r = 0; r < p; r++) {
            const double xl = k[5 * r], xr = k[5 * r + 1], yv = k[5 * r + 2], al = k[5 * r + 3], ar = k[5 * r + 4];
            if (!(xr > xl)) {
                out[r] = INFINITY;
                continue;
            }
            const double inv = 1.0 / (xr - xl);
            const double th_l = -al * inv, th_r = ar * inv, f_l = xr * al * inv, f_r = -xl * ar * inv;
            double cost = 0.0;
            for (Py_ssize_t s = 0; s < n; s++) {
                const Py_ssize_t j0 = first[s], j1 = s + 1 < n ? first[s + 1] : m;
                double hr = 1.0, hi = 0.0, zr = 0.0, zi = 0.0, dphi = 0.0;
                for (Py_ssize_t j = j0; j < j1; j++) {
                    const double dth = th_l * dl[j] + th_r * dr[j];
                    const double fwd = f_l * dl[j] + f_r * dr[j];
                    const double lat = -yv * dth;
                    double sn, cs;
                    if (fabs(dth) > SMALL_ANGLE) {
                        sn = sin(dth) / dth;
                        cs = (1.0 - cos(dth)) / dth;
                    } else {
                        const double d2 = dth * dth;
                        sn = 1.0 + d2 * (-1.0 / 6 + d2 * (1.0 / 120 - d2 * (1.0 / 5040)));
                        cs = dth * (0.5 + d2 * (-1.0 / 24 + d2 * (1.0 / 720 - d2 * (1.0 / 40320))));
                    }
                    const double br = sn * fwd - cs * lat, bi = cs * fwd + sn * lat;  /* body increment */
                    zr += br * hr - bi * hi;
                    zi += br * hi + bi * hr;
                    const double rr = 1.0 - dth * cs, ri = dth * sn;  /* exp(i dth) */
                    const double t = hr * rr - hi * ri;
                    hi = hr * ri + hi * rr;
                    hr = t;
                    dphi += dth;
                }
                const double ex = rdx[s] - zr, ey = rdy[s] - zi, ephi = wrap_angle(rdphi[s] - dphi);
                cost += ex * ex + ey * ey + ephi * ephi;
            }
            out[r] = cost;
        }
        Py_END_ALLOW_THREADS
        Py_INCREF(Py_None);
        ret = Py_None;
    }
done:
    if (got >= 8) PyBuffer_Release(&bout);
    if (got >= 7) PyBuffer_Release(&bdphi);
    if (got >= 6) PyBuffer_Release(&bdy);
    if (got >= 5) PyBuffer_Release(&bdx);
    if (got >= 4) PyBuffer_Release(&bfirst);
    if (got >= 3) PyBuffer_Release(&bdr);
    if (got >= 2) PyBuffer_Release(&bdl);
    if (got >= 1) PyBuffer_Release(&bk);
    return ret;
}

static PyMethodDef methods[] = {
    {"segment_cost", segment_cost, METH_VARARGS, "Mandow 2007 eq. (13) for parameter rows (see segments.segment_cost)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef cost_module = {PyModuleDef_HEAD_INIT, "_cost", "Mandow 2007 eq. (13) in C", -1, methods};

PyMODINIT_FUNC PyInit__cost(void) { return PyModule_Create(&cost_module); }
