/* The testbed's per-step drive-train and tire arithmetic (bench.sim.testbed.run_physics), in C.
 *
 * A second implementation of the loop body of ``run_physics`` in bench/sim/testbed.py (the Python
 * loop is the reference; tests/sim/test_kernel.py checks that both give the same trace, bit for bit,
 * on every feature the loop has).  It computes, for one physics step, what the Python loop computes
 * between the pybullet queries and ``applyExternalForce``: the rate-limited references, Yu's PID
 * (bench.sim.drive.SidePid), the motor line (bench.sim.drive.motor_law), the friction coefficient
 * (bench.sim.tire.friction_coefficient), the tire law at each wheel contact (bench.sim.tire.tire_law),
 * the standing-wheel patch spring, the semi-implicit wheel-spin update, and the log row.
 *
 * Same bits as the Python loop because it does the same IEEE-754 double operations in the same order:
 * every expression keeps the Python expression's evaluation order; exp, tanh, cos and sqrt are the C
 * library's, which CPython's math module calls too; math.hypot is not the C library's hypot in CPython
 * (its own correctly-rounding algorithm), so it is called through the Python function passed in.  Built
 * with -ffp-contract=off (no fused multiply-add).  Python raises ZeroDivisionError where C would divide
 * by zero: the same checks are made here.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#define N_REC 28
#define N_CONST 27
#define SOIL_EPS 0.01  /* bench/sim/testbed.py SOIL_EPS */

typedef struct {
    double x_min, x_max, y_min, y_max, mu_scale, t_period;
} Patch;

typedef struct {
    PyObject_HEAD
    /* constants (bound once per run, from the Python side) */
    double dt, lim, eps, k_max, k_hold, k_hold_dt, mu_roll, pid_slope, mu_sa, mu_op, v_max, i_max, pid_dt;
    double i_side, k_amp, r_eff[2], dt_rr[2];
    double c_lon, c_lat, mu_lat_ratio, eps2, speed_decay;   /* tire law */
    double pid_kp, pid_ki, pid_kd, pid_scale;  /* SidePid */
    double m_gear, m_KB, m_KT, m_Ra, m_imax, m_pmax, m_slope_free, m_k;  /* motor_law */
    int janosi, pid_every, pid_adds_slope;
    int soil;  /* Bekker soil force model (bench/sim/soil.py), set by set_soil; 0 = rigid ground */
    double soil_z_coef, soil_z_exp, soil_rc_coef, soil_n1, soil_tan_phi, soil_ca_coef;
    int tire;  /* per-wheel patch and loaded radius from the load (bench.sim.tire.tire_contact), set by set_tire */
    double tire_p_coef, tire_q_coef;
    long n_steps;
    Patch *patches;
    Py_ssize_t n_patches;
    double *ref_l, *ref_r;  /* per-step references, n_steps + 1 */
    PyObject *hypot;        /* math.hypot */
    /* state */
    double w[2], th[2], tau[2], cur[2], refs[2], volts[2];
    double pid_integ[2], pid_prev[2];
    int pid_has_prev[2];
    double defl[4][2];
    double normal[4], cpos[4][3], cnorm[4][3];
    int has_cpos[4];
    /* log */
    double *log;
    Py_ssize_t log_rows, log_cap;
} Kernel;

static int py_hypot(Kernel *self, double a, double b, double *out) {
    PyObject *args[2];
    args[0] = PyFloat_FromDouble(a);
    args[1] = PyFloat_FromDouble(b);
    if (!args[0] || !args[1]) {
        Py_XDECREF(args[0]);
        Py_XDECREF(args[1]);
        return -1;
    }
    PyObject *r = PyObject_Vectorcall(self->hypot, args, 2, NULL);
    Py_DECREF(args[0]);
    Py_DECREF(args[1]);
    if (!r) return -1;
    *out = PyFloat_AsDouble(r);
    Py_DECREF(r);
    if (*out == -1.0 && PyErr_Occurred()) return -1;
    return 0;
}

static int zero_division(void) {
    PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");
    return -1;
}

/* Python's max(a, b) on floats: b only when b > a */
static inline double py_max(double a, double b) { return (b > a) ? b : a; }

static int read_doubles(PyObject *seq, double *out, Py_ssize_t n, const char *what) {
    PyObject *fast = PySequence_Fast(seq, what);
    if (!fast) return -1;
    if (PySequence_Fast_GET_SIZE(fast) != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", what, n, PySequence_Fast_GET_SIZE(fast));
        Py_DECREF(fast);
        return -1;
    }
    PyObject **items = PySequence_Fast_ITEMS(fast);
    for (Py_ssize_t i = 0; i < n; i++) {
        out[i] = PyFloat_AsDouble(items[i]);
        if (out[i] == -1.0 && PyErr_Occurred()) {
            Py_DECREF(fast);
            return -1;
        }
    }
    Py_DECREF(fast);
    return 0;
}

static double *read_array(PyObject *seq, Py_ssize_t n, const char *what) {
    double *a = PyMem_Malloc(sizeof(double) * (size_t)(n > 0 ? n : 1));
    if (!a) {
        PyErr_NoMemory();
        return NULL;
    }
    if (read_doubles(seq, a, n, what) < 0) {
        PyMem_Free(a);
        return NULL;
    }
    return a;
}

static void Kernel_dealloc(Kernel *self) {
    PyMem_Free(self->patches);
    PyMem_Free(self->ref_l);
    PyMem_Free(self->ref_r);
    PyMem_Free(self->log);
    Py_XDECREF(self->hypot);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* Kernel(consts, ints, patches, ref_l, ref_r, hypot): see bench.sim.testbed._kernel_for */
static int Kernel_init(Kernel *self, PyObject *args, PyObject *kwds) {
    PyObject *consts, *ints, *patches, *ref_l, *ref_r, *hypot;
    if (!PyArg_ParseTuple(args, "OOOOOO", &consts, &ints, &patches, &ref_l, &ref_r, &hypot)) return -1;
    /* a second __init__ starts afresh (no buffer of the first is kept) */
    PyMem_Free(self->patches);
    PyMem_Free(self->ref_l);
    PyMem_Free(self->ref_r);
    PyMem_Free(self->log);
    self->patches = NULL;
    self->ref_l = self->ref_r = self->log = NULL;
    Py_CLEAR(self->hypot);
    double c[N_CONST];
    if (read_doubles(consts, c, N_CONST, "consts") < 0) return -1;
    double iv[4];
    if (read_doubles(ints, iv, 4, "ints") < 0) return -1;
    self->dt = c[0]; self->lim = c[1]; self->eps = c[2]; self->k_max = c[3]; self->k_hold = c[4];
    self->k_hold_dt = c[5]; self->mu_roll = c[6]; self->pid_slope = c[7]; self->mu_sa = c[8]; self->mu_op = c[9];
    self->v_max = c[10]; self->i_max = c[11]; self->pid_dt = c[12]; self->i_side = c[13]; self->k_amp = c[14];
    self->r_eff[0] = c[15]; self->r_eff[1] = c[16]; self->dt_rr[0] = c[17]; self->dt_rr[1] = c[18];
    self->c_lon = c[19]; self->c_lat = c[20]; self->mu_lat_ratio = c[21]; self->eps2 = c[22];
    self->pid_kp = c[23]; self->pid_ki = c[24]; self->pid_kd = c[25];
    self->speed_decay = c[26];
    self->janosi = (int)iv[0]; self->pid_every = (int)iv[1]; self->pid_adds_slope = (int)iv[2];
    self->n_steps = (long)iv[3];
    if (self->pid_every < 1) {
        PyErr_SetString(PyExc_ValueError, "pid_every must be >= 1");
        return -1;
    }
    self->pid_scale = 0.0;
    /* motor and pid scale come from set_motor (kept apart: they are another spec) */
    PyObject *pf = PySequence_Fast(patches, "patches");
    if (!pf) return -1;
    self->n_patches = PySequence_Fast_GET_SIZE(pf);
    self->patches = PyMem_Malloc(sizeof(Patch) * (size_t)(self->n_patches > 0 ? self->n_patches : 1));
    if (!self->patches) {
        Py_DECREF(pf);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < self->n_patches; i++) {
        double v[6];
        if (read_doubles(PySequence_Fast_GET_ITEM(pf, i), v, 6, "patch") < 0) {
            Py_DECREF(pf);
            return -1;
        }
        Patch *q = &self->patches[i];
        q->x_min = v[0]; q->x_max = v[1]; q->y_min = v[2]; q->y_max = v[3]; q->mu_scale = v[4]; q->t_period = v[5];
    }
    Py_DECREF(pf);
    Py_ssize_t n = (Py_ssize_t)self->n_steps + 1;
    if (!(self->ref_l = read_array(ref_l, n, "ref_l"))) return -1;
    if (!(self->ref_r = read_array(ref_r, n, "ref_r"))) return -1;
    Py_INCREF(hypot);
    self->hypot = hypot;
    memset(self->w, 0, sizeof self->w); memset(self->th, 0, sizeof self->th);
    memset(self->tau, 0, sizeof self->tau); memset(self->cur, 0, sizeof self->cur);
    memset(self->refs, 0, sizeof self->refs); memset(self->volts, 0, sizeof self->volts);
    memset(self->pid_integ, 0, sizeof self->pid_integ); memset(self->pid_prev, 0, sizeof self->pid_prev);
    memset(self->pid_has_prev, 0, sizeof self->pid_has_prev); memset(self->defl, 0, sizeof self->defl);
    memset(self->normal, 0, sizeof self->normal); memset(self->has_cpos, 0, sizeof self->has_cpos);
    self->soil = self->tire = 0;
    self->log_cap = n;
    self->log_rows = 0;
    self->log = PyMem_Malloc(sizeof(double) * N_REC * (size_t)n);
    if (!self->log) {
        PyErr_NoMemory();
        return -1;
    }
    return 0;
}

/* set_motor(gear, K_B, K_T, R_a, i_max, p_max, slope_free, k, pid_scale) */
static PyObject *Kernel_set_motor(Kernel *self, PyObject *args) {
    if (!PyArg_ParseTuple(args, "ddddddddd", &self->m_gear, &self->m_KB, &self->m_KT, &self->m_Ra, &self->m_imax,
                          &self->m_pmax, &self->m_slope_free, &self->m_k, &self->pid_scale))
        return NULL;
    Py_RETURN_NONE;
}

/* set_soil(z_coef, z_exp, rc_coef, n + 1, tan_phi, ca_coef): bench.sim.soil.soil_constants; switches the soil on */
static PyObject *Kernel_set_soil(Kernel *self, PyObject *args) {
    if (!PyArg_ParseTuple(args, "dddddd", &self->soil_z_coef, &self->soil_z_exp, &self->soil_rc_coef, &self->soil_n1,
                          &self->soil_tan_phi, &self->soil_ca_coef))
        return NULL;
    self->soil = 1;
    Py_RETURN_NONE;
}

/* set_tire(patch_coef, radius_coef): bench.sim.tire.tire_contact; switches the per-wheel tire contact on */
static PyObject *Kernel_set_tire(Kernel *self, PyObject *args) {
    if (!PyArg_ParseTuple(args, "dd", &self->tire_p_coef, &self->tire_q_coef)) return NULL;
    self->tire = 1;
    Py_RETURN_NONE;
}

/* set_side(s, w, ref, integ, prev_ref): the initial-speed preload of one side */
static PyObject *Kernel_set_side(Kernel *self, PyObject *args) {
    int s;
    double w, ref, integ, prev;
    if (!PyArg_ParseTuple(args, "idddd", &s, &w, &ref, &integ, &prev)) return NULL;
    if (s < 0 || s > 1) {
        PyErr_SetString(PyExc_IndexError, "side must be 0 or 1");
        return NULL;
    }
    self->w[s] = w;
    self->refs[s] = ref;
    self->pid_integ[s] = integ;
    self->pid_prev[s] = prev;
    self->pid_has_prev[s] = 1;
    Py_RETURN_NONE;
}

/* SidePid.__call__ */
static double pid_call(Kernel *self, int s, double ref, double w, double dt) {
    double e = self->pid_scale * (ref - w);
    double d_ref = self->pid_has_prev[s] ? self->pid_scale * (ref - self->pid_prev[s]) / dt : 0.0;
    self->pid_prev[s] = ref;
    self->pid_has_prev[s] = 1;
    double integ = self->pid_integ[s] + e * dt;
    double u = self->pid_kp * e + self->pid_ki * integ + self->pid_kd * d_ref;
    if (u > self->v_max) {
        u = self->v_max;
        if (e < 0) self->pid_integ[s] = integ;
    } else if (u < -self->v_max) {
        u = -self->v_max;
        if (e > 0) self->pid_integ[s] = integ;
    } else {
        self->pid_integ[s] = integ;
    }
    return u;
}

/* motor_law's law(volt, w) -> (tq, cu, dtq) */
static int motor_call(Kernel *self, double volt, double w, double *tq, double *cu, double *dtq) {
    double wm = self->m_gear * w;
    double cur = (volt - self->m_KB * wm) / self->m_Ra;
    double slope = self->m_slope_free;
    if (cur > self->m_imax) {
        cur = self->m_imax;
        slope = 0.0;
    } else if (cur < -self->m_imax) {
        cur = -self->m_imax;
        slope = 0.0;
    }
    double tau_m = self->m_KT * cur;
    if (self->m_pmax > 0.0 && fabs(tau_m * wm) > self->m_pmax) {
        tau_m = copysign(self->m_pmax / py_max(fabs(wm), 1e-9), tau_m);
        cur = tau_m / self->m_KT;
        slope = -fabs(tau_m) / py_max(fabs(w), 1e-9) * (tau_m * w > 0 ? 1.0 : -1.0);
    }
    *tq = self->m_k * tau_m;
    *cu = cur;
    *dtq = self->m_k * slope;
    return 0;
}

/* tire_law's janosi / coulomb -> (f_lon, f_lat, stiff) */
static int law_call(Kernel *self, double s_lon, double s_lat, double u, double v_lon, double normal, double mu,
                    double ps, double *f_lon, double *f_lat, double *stiff) {
    if (normal <= 0.0) {
        *f_lon = *f_lat = *stiff = 0.0;
        return 0;
    }
    double s;
    if (py_hypot(self, s_lon, s_lat, &s) < 0) return -1;
    if (s < 1e-12) {
        *f_lon = *f_lat = 0.0;
        *stiff = self->k_max;
        return 0;
    }
    if (self->speed_decay > 0.0) mu = mu / (1.0 + self->speed_decay * s);  /* Dugoff: tire_law's speed_decay */
    double mag;
    if (self->janosi) {
        double v_ref = fabs(u), h;
        if (py_hypot(self, v_lon, s_lat, &h) < 0) return -1;
        if (h > v_ref) v_ref = h;
        if (self->eps > v_ref) v_ref = self->eps;
        if (v_ref == 0.0) return zero_division();
        double z_lon = s_lon * (self->c_lon * ps) / v_ref;
        double z_lat = s_lat * (self->c_lat * ps) / v_ref;
        double z;
        if (py_hypot(self, z_lon, z_lat, &z) < 0) return -1;
        if (z == 0.0) return zero_division();
        double frac = z < 1e-6 ? 0.5 * z : 1.0 - (1.0 - exp(-z)) / z;
        double a = (1.0 - frac) / z, b = frac / s;
        mag = mu * normal * frac;
        if (mag > self->k_max * s) mag = self->k_max * s;
        *f_lon = -mag * (a * z_lon + b * s_lon);
        *f_lat = -mag * self->mu_lat_ratio * (a * z_lat + b * s_lat);
        *stiff = mag / s;
        return 0;
    }
    mag = mu * normal * s / sqrt(s * s + self->eps2);
    if (mag > self->k_max * s) mag = self->k_max * s;
    *f_lon = -mag * s_lon / s;
    *f_lat = -mag * self->mu_lat_ratio * s_lat / s;
    *stiff = mag / s;
    return 0;
}

static int get3(PyObject *t, double *out, const char *what) { return read_doubles(t, out, 3, what); }

/* step(k, pos, orn, lin, ang, R, contacts) -> ((fx, fy, fz), (mx, my, mz)), or None after the last row */
static PyObject *Kernel_step(Kernel *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "step(k, pos, orn, lin, ang, R, contacts)");
        return NULL;
    }
    long k = PyLong_AsLong(args[0]);
    if (k == -1 && PyErr_Occurred()) return NULL;
    double pos[3], orn[4], lin[3], ang[3], R[9];
    if (get3(args[1], pos, "pos") < 0 || read_doubles(args[2], orn, 4, "orn") < 0 || get3(args[3], lin, "lin") < 0 ||
        get3(args[4], ang, "ang") < 0 || read_doubles(args[5], R, 9, "R") < 0)
        return NULL;
    const double dt = self->dt;
    double *refs = self->refs;
    if (k >= 0) {
        if (k > self->n_steps) {
            PyErr_SetString(PyExc_IndexError, "step beyond the references");
            return NULL;
        }
        double dref = self->ref_l[k] - refs[0];
        refs[0] += fabs(dref) <= self->lim ? dref : copysign(self->lim, dref);
        dref = self->ref_r[k] - refs[1];
        refs[1] += fabs(dref) <= self->lim ? dref : copysign(self->lim, dref);
    }
    const double fwd[3] = {R[0], R[3], R[6]};
    const double px = pos[0], py = pos[1], pz = pos[2];
    const double lx_ = lin[0], ly_ = lin[1], lz_ = lin[2];
    const double wx_ = ang[0], wy_ = ang[1], wz_ = ang[2];
    double *normal = self->normal;
    normal[0] = normal[1] = normal[2] = normal[3] = 0.0;
    PyObject *cf = PySequence_Fast(args[6], "contacts");
    if (!cf) return NULL;
    Py_ssize_t nc = PySequence_Fast_GET_SIZE(cf);
    for (Py_ssize_t j = 0; j < nc; j++) {
        PyObject *c = PySequence_Fast_GET_ITEM(cf, j);
        PyObject *cli = PySequence_GetItem(c, 3);
        if (!cli) goto fail;
        long li = PyLong_AsLong(cli);
        Py_DECREF(cli);
        if (li == -1 && PyErr_Occurred()) goto fail;
        if (li < 0) continue;
        if (li > 3) {
            PyErr_SetString(PyExc_IndexError, "list index out of range");
            goto fail;
        }
        PyObject *o9 = PySequence_GetItem(c, 9), *o6 = PySequence_GetItem(c, 6), *o7 = PySequence_GetItem(c, 7);
        int bad = !o9 || !o6 || !o7;
        double nf = bad ? 0.0 : PyFloat_AsDouble(o9);
        if (!bad && nf == -1.0 && PyErr_Occurred()) bad = 1;
        if (!bad && (get3(o6, self->cpos[li], "contact position") < 0 || get3(o7, self->cnorm[li], "contact normal") < 0))
            bad = 1;
        Py_XDECREF(o9);
        Py_XDECREF(o6);
        Py_XDECREF(o7);
        if (bad) goto fail;
        normal[li] += nf;
        self->has_cpos[li] = 1;
    }
    Py_DECREF(cf);
    cf = NULL;

    double fx = 0.0, fy = 0.0, fz = 0.0, mx = 0.0, my = 0.0, mz = 0.0;
    const double t_now = (double)k * dt;
    const int pid_tick = k % self->pid_every == 0;
    for (int s = 0; s < 2; s++) {
        double ws = self->w[s];
        if (pid_tick) self->volts[s] = pid_call(self, s, refs[s], ws, self->pid_dt);
        double volt = self->volts[s];
        double tq, cu, dtq;
        motor_call(self, volt, ws, &tq, &cu, &dtq);
        if (pid_tick && self->pid_adds_slope && fabs(volt) < self->v_max && fabs(cu) < self->i_max) dtq += self->pid_slope;
        /* friction_coefficient(mu_sa, mu_op, tq, ws) */
        double drive = 0.5 * (1.0 + tanh(tq * ws / 0.05));
        double mu_base = self->mu_op + (self->mu_sa - self->mu_op) * drive;
        double rr = self->r_eff[s];
        double u = rr * ws;
        double f_lon_sum = 0.0, stiff_sum = 0.0, n_side = 0.0;
        double sx = 0.0, sy = 0.0, sz = 0.0, smx = 0.0, smy = 0.0, smz = 0.0;
        for (int i = 2 * s; i < 2 * s + 2; i++) {
            double nf = normal[i];
            if (nf <= 0.0 || !self->has_cpos[i]) continue;
            double ps = 1.0, q = 1.0;  /* this wheel's patch length and loaded rolling radius r q */
            if (self->tire) {
                ps = self->tire_p_coef * sqrt(nf);
                q = 1.0 - self->tire_q_coef * nf;
            }
            double ui = u * q;
            n_side += nf * q;
            double cx = self->cpos[i][0], cy_ = self->cpos[i][1], cz = self->cpos[i][2];
            double rx = cx - px, ry = cy_ - py, rz = cz - pz;
            double vcx = lx_ + wy_ * rz - wz_ * ry;
            double vcy = ly_ + wz_ * rx - wx_ * rz;
            double vcz = lz_ + wx_ * ry - wy_ * rx;
            /* _wheel_frame(fwd, n) */
            double nx = self->cnorm[i][0], ny = self->cnorm[i][1], nz = self->cnorm[i][2];
            double dot = fwd[0] * nx + fwd[1] * ny + fwd[2] * nz;
            double ex = fwd[0] - dot * nx, ey = fwd[1] - dot * ny, ez = fwd[2] - dot * nz;
            double en = sqrt(ex * ex + ey * ey + ez * ez);
            if (en == 0.0) return zero_division(), NULL;
            ex = ex / en;
            ey = ey / en;
            ez = ez / en;
            double lx = ny * ez - nz * ey, ly = nz * ex - nx * ez, lz = nx * ey - ny * ex;
            double v_lon = vcx * ex + vcy * ey + vcz * ez;
            double v_lat = vcx * lx + vcy * ly + vcz * lz;
            double mu = mu_base;
            double f_rc = 0.0;
            if (self->soil) {  /* Bekker sinkage under the current load; shear strength c A + W tan phi */
                double z = self->soil_z_coef * pow(nf, self->soil_z_exp);
                mu = self->soil_tan_phi + self->soil_ca_coef * sqrt(z) / nf;
                /* compaction resistance: a force on the body against the travel (Wong Ch. 2), slope capped at k_max */
                double rc = self->soil_rc_coef * pow(z, self->soil_n1);
                double e_rc = rc / self->k_max;
                if (!(e_rc > SOIL_EPS)) e_rc = SOIL_EPS;
                f_rc = -rc * tanh(v_lon / e_rc);
            }
            for (Py_ssize_t k = 0; k < self->n_patches; k++) {
                const Patch *fp = &self->patches[k];
                if (fp->x_min <= cx && cx <= fp->x_max && fp->y_min <= cy_ && cy_ <= fp->y_max) {
                    double scale = fp->mu_scale;
                    if (fp->t_period > 0)
                        scale = 1.0 + (fp->mu_scale - 1.0) * 0.5 * (1 - cos(2 * M_PI * t_now / fp->t_period));
                    mu *= scale;
                }
            }
            double f_lon, f_lat, stiff;
            if (law_call(self, v_lon - ui, v_lat, ui, v_lon, nf, mu, ps, &f_lon, &f_lat, &stiff) < 0) return NULL;
            double *d = self->defl[i];
            if (fabs(ui) < self->eps && fabs(v_lon) < self->eps && fabs(v_lat) < self->eps) {
                d[0] += (v_lon - ui) * dt;
                d[1] += v_lat * dt;
                f_lon -= self->k_hold * d[0];
                f_lat -= self->k_hold * d[1];
                double f_abs;
                if (py_hypot(self, f_lon, f_lat, &f_abs) < 0) return NULL;
                double f_lim = mu * nf;
                if (f_abs > f_lim) {
                    double scale = f_lim / f_abs;
                    f_lon = f_lon * scale;
                    f_lat = f_lat * scale;
                    d[0] *= scale;
                    d[1] *= scale;
                }
                stiff += self->k_hold_dt;
            } else {
                d[0] = d[1] = 0.0;
            }
            f_lon_sum += q * f_lon;
            stiff_sum += q * q * stiff;
            double f_body = f_lon + f_rc;  /* the tire's shear and the soil's compaction resistance (0 off soil) */
            double gx = f_body * ex + f_lat * lx;
            double gy = f_body * ey + f_lat * ly;
            double gz = f_body * ez + f_lat * lz;
            fx += gx;
            fy += gy;
            fz += gz;
            mx += ry * gz - rz * gy;
            my += rz * gx - rx * gz;
            mz += rx * gy - ry * gx;
            double sq = stiff * q;
            sx += sq * ex;
            sy += sq * ey;
            sz += sq * ez;
            smx += sq * (ry * ez - rz * ey);
            smy += sq * (rz * ex - rx * ez);
            smz += sq * (rx * ey - ry * ex);
        }
        double sgn = tanh(u / 0.01);
        /* rolling resistance: mu_roll N on rigid ground; none on soil (the compaction resistance acts on the body) */
        double roll = self->soil ? 0.0 : self->mu_roll * n_side * rr;
        double t_roll = roll * sgn;
        double dt_roll = roll * (1 - sgn * sgn) * rr / 0.01;
        double num = tq - rr * f_lon_sum - t_roll;
        double den = self->i_side - dt * dtq + self->dt_rr[s] * stiff_sum + dt * dt_roll;
        if (den == 0.0) return zero_division(), NULL;
        double dw = dt * num / den;
        double c = rr * dw;
        fx += c * sx;
        fy += c * sy;
        fz += c * sz;
        mx += c * smx;
        my += c * smy;
        mz += c * smz;
        ws += dw;
        self->w[s] = ws;
        self->th[s] += ws * dt;
        self->tau[s] = tq + dtq * dw;
        if (self->k_amp == 0.0) return zero_division(), NULL;
        self->cur[s] = cu + dtq * dw / self->k_amp;
    }
    if (k >= 0) {
        if (self->log_rows >= self->log_cap) {
            PyErr_SetString(PyExc_IndexError, "log full");
            return NULL;
        }
        double *row = self->log + N_REC * self->log_rows++;
        const double vals[N_REC] = {
            t_now, px, py, pz, orn[0], orn[1], orn[2], orn[3], lx_, ly_, lz_, wx_, wy_, wz_,
            self->w[0], self->w[1], self->th[0], self->th[1], self->tau[0], self->tau[1], self->cur[0], self->cur[1],
            refs[0], refs[1], normal[0], normal[1], normal[2], normal[3],
        };
        memcpy(row, vals, sizeof vals);
        if (k == self->n_steps) Py_RETURN_NONE;
    } else {
        self->th[0] = self->th[1] = 0.0;
    }
    return Py_BuildValue("((ddd)(ddd))", fx, fy, fz, mx, my, mz);
fail:
    Py_XDECREF(cf);
    return NULL;
}

/* log() -> bytes of the logged rows (float64, row-major, N_REC columns) */
static PyObject *Kernel_log(Kernel *self, PyObject *Py_UNUSED(ignored)) {
    return PyBytes_FromStringAndSize((const char *)self->log, (Py_ssize_t)(sizeof(double) * N_REC * self->log_rows));
}

static PyMethodDef Kernel_methods[] = {
    {"set_motor", (PyCFunction)Kernel_set_motor, METH_VARARGS, "motor-line and PID-scale constants"},
    {"set_soil", (PyCFunction)Kernel_set_soil, METH_VARARGS, "Bekker soil constants (switches the soil on)"},
    {"set_tire", (PyCFunction)Kernel_set_tire, METH_VARARGS, "tire contact constants (switches the tire on)"},
    {"set_side", (PyCFunction)Kernel_set_side, METH_VARARGS, "initial-speed preload of one side"},
    {"step", (PyCFunction)(void (*)(void))Kernel_step, METH_FASTCALL, "one physics step's forces, and its log row"},
    {"log", (PyCFunction)Kernel_log, METH_NOARGS, "the logged rows as float64 bytes"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "bench.sim._kernel.Kernel",
    .tp_basicsize = sizeof(Kernel),
    .tp_dealloc = (destructor)Kernel_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Per-step drive-train and tire arithmetic of bench.sim.testbed.run_physics",
    .tp_methods = Kernel_methods,
    .tp_init = (initproc)Kernel_init,
    .tp_new = PyType_GenericNew,
};

static struct PyModuleDef kernel_module = {
    PyModuleDef_HEAD_INIT, "_kernel", "C step of the skidbench testbed (bench.sim.testbed)", -1, NULL,
};

PyMODINIT_FUNC PyInit__kernel(void) {
    if (PyType_Ready(&KernelType) < 0) return NULL;
    PyObject *m = PyModule_Create(&kernel_module);
    if (!m) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(m, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(m);
        return NULL;
    }
    PyModule_AddIntConstant(m, "N_REC", N_REC);
    return m;
}
