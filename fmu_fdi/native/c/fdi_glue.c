/* fdi_glue.c - instance, state machine, variables, logging and FMU state shared by fmi2.c and
 * fmi3.c (C99). See fdi_glue.h. No global mutable state: the only file-scope data are
 * constant tables. */
#include "fdi_glue.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#define INSTANCE_MAGIC 0x46444949u  /* "FDII" */
#define STATE_MAGIC 0x46444953u     /* "FDIS" */
static const unsigned char IMAGE_MAGIC[8] = {'f', 'd', 'i', 'F', 'M', 'U', '0', '1'};

const char *const FDI_CATEGORY_NAMES[FDI_N_CATEGORIES] = {
    "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal",
    "logAll", "logFdiEvents", "logFdiInput", "logFdiState", "logFdiNumeric",
};

const signed char FDI_OUTPUT_KIND_TABLE[FDI_N_OUTPUTS > 0 ? FDI_N_OUTPUTS : 1] = FDI_OUTPUT_KINDS;
#define OUTPUT_KINDS FDI_OUTPUT_KIND_TABLE
static const double INPUT_STARTS[FDI_N_INPUTS > 0 ? FDI_N_INPUTS : 1] = FDI_INPUT_STARTS;
static const char *const VARIABLE_NAMES[] = FDI_VARIABLE_NAMES;  /* by value reference */
static const char *const FAULT_NAMES[FDI_N_FAULTS > 0 ? FDI_N_FAULTS : 1] = FDI_FAULT_NAMES;
static const char *const KIND_NAMES[] = {"Real", "Boolean", "Integer"};

struct fdi_state_obj {
    unsigned long magic;
    const fdi_instance *owner;
    size_t len;
    unsigned char data[];  /* the image */
};

static size_t align8(size_t n) { return (n + 7u) & ~(size_t)7u; }

size_t fdi_instance_bytes(const char *name) {
    return align8(sizeof(fdi_instance)) + align8(sizeof(double) * (FDI_N_INPUTS + 1)) +
           align8(strlen(name ? name : "") + 1) + align8(fdi_runtime_size(&FDI_DESIGN));
}

int fdi_model_consistent(char *why, size_t whylen) {
    const fdi_design *d = &FDI_DESIGN;
    if (fdi_n_u(d) + fdi_n_y(d) != (size_t)FDI_N_INPUTS || fdi_n_outputs(d) != (size_t)FDI_N_OUTPUTS) {
        snprintf(why, whylen, "the compiled design has %zu inputs and %zu outputs, the model description %d and %d "
                 "(sources of two different builds mixed)", fdi_n_u(d) + fdi_n_y(d), fdi_n_outputs(d),
                 FDI_N_INPUTS, FDI_N_OUTPUTS);
        return 0;
    }
    return 1;
}

fdi_instance *fdi_instance_init(void *block, size_t nbytes, const char *name, fdi_emit_fn emit, void *host,
                                fdi_alloc_fn alloc, fdi_release_fn release, int logging_on) {
    unsigned char *p = block;
    fdi_instance *fi = block;
    size_t need = fdi_instance_bytes(name);
    if (!block || nbytes < need) return NULL;
    memset(block, 0, need);
    p += align8(sizeof(fdi_instance));
    fi->inputs = (double *)(void *)p;
    p += align8(sizeof(double) * (FDI_N_INPUTS + 1));
    fi->name = (char *)p;
    strcpy(fi->name, name ? name : "");
    p += align8(strlen(fi->name) + 1);
    fi->rt = (fdi_runtime *)(void *)p;
    fi->emit = emit;
    fi->host = host;
    fi->alloc = alloc;
    fi->release = release;
    fi->logging_on = logging_on != 0;
    fi->categories = (1u << FDI_N_CATEGORIES) - 1u;
    if (fdi_runtime_init(fi->rt, &FDI_DESIGN, fdi_runtime_size(&FDI_DESIGN)) != FDI_OK) return NULL;
    fi->magic = INSTANCE_MAGIC;
    fdi_instance_reset(fi);
    return fi;
}

int fdi_is_instance(const void *p) { return p != NULL && ((const fdi_instance *)p)->magic == INSTANCE_MAGIC; }

void fdi_instance_forget(fdi_instance *fi) {
    if (fi) fi->magic = 0;
}

void fdi_instance_reset(fdi_instance *fi) {
    /* as freshly instantiated: the tunable parameter back to its start value too */
    fdi_runtime_reset(fi->rt);
    fdi_runtime_set_threshold_scale(fi->rt, 1.0, fi->why, sizeof fi->why);
    fi->outputs = fdi_runtime_outputs(fi->rt);
    memcpy(fi->inputs, INPUT_STARTS, sizeof(double) * FDI_N_INPUTS);
    fi->time = 0.0;
    fi->mode = FDI_M_INSTANTIATED;
    fi->last_detected = 0;
    fi->last_isolated = 0;
}

const char *fdi_mode_name(int mode) {
    static const char *const names[] = {"Instantiated", "Initialization Mode", "Event Mode", "Step Mode",
                                        "Terminated", "Error"};
    return mode >= 0 && mode <= FDI_M_ERROR ? names[mode] : "?";
}

static int category_on(const fdi_instance *fi, int status, int category) {
    if (status >= FDI_S_ERROR) return 1;  /* the reason for an Error always reaches the host */
    return fi->logging_on && (fi->categories & (1u << category));
}

void fdi_log(fdi_instance *fi, int status, int category, const char *fmt, ...) {
    va_list ap;
    if (!fi->emit || !category_on(fi, status, category)) return;
    if (status == FDI_S_WARNING && category == FDI_C_ALL) category = FDI_C_WARNING;
    if (status == FDI_S_DISCARD && category == FDI_C_ALL) category = FDI_C_DISCARD;
    if (status == FDI_S_ERROR) category = FDI_C_ERROR;
    if (status == FDI_S_FATAL) category = FDI_C_FATAL;
    va_start(ap, fmt);
    vsnprintf(fi->msg, sizeof fi->msg, fmt, ap);
    va_end(ap);
    fi->emit(fi->host, fi->name, status, FDI_CATEGORY_NAMES[category], fi->msg);
}

int fdi_not_allowed(fdi_instance *fi, const char *fn, unsigned allowed) {
    char list[160] = "";
    int m;
    for (m = 0; m <= FDI_M_ERROR; m++) {
        if (allowed & FDI_ALLOW(m)) {
            if (list[0]) strncat(list, ", ", sizeof list - strlen(list) - 1);
            strncat(list, fdi_mode_name(m), sizeof list - strlen(list) - 1);
        }
    }
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s called in %s: allowed only in %s%s", fn, fdi_mode_name(fi->mode),
            list, fi->mode == FDI_M_ERROR ? " (an earlier call failed: reset or free the instance)"
                                          : "; the instance is now in the Error state");
    fi->mode = FDI_M_ERROR;
    return 0;
}

int fdi_set_logging(fdi_instance *fi, int on, size_t n, const char *const categories[], const char *fn) {
    unsigned mask = 0;
    size_t i;
    int c;
    if (n > 0 && !categories) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: %zu categories but no array", fn, n);
        return FDI_S_ERROR;
    }
    for (i = 0; i < n; i++) {
        for (c = 0; c < FDI_N_CATEGORIES; c++)
            if (categories[i] && strcmp(categories[i], FDI_CATEGORY_NAMES[c]) == 0) break;
        if (c == FDI_N_CATEGORIES) {
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: unknown log category '%s' (known: logStatusWarning, "
                    "logStatusDiscard, logStatusError, logStatusFatal, logAll, logFdiEvents, logFdiInput, logFdiState, "
                    "logFdiNumeric)",
                    fn, categories[i] ? categories[i] : "(null)");
            return FDI_S_ERROR;  /* settings unchanged */
        }
        mask |= 1u << c;
    }
    fi->logging_on = on != 0;
    fi->categories = n == 0 ? (1u << FDI_N_CATEGORIES) - 1u : mask;
    return FDI_S_OK;
}

/* ---- variables ------------------------------------------------------------------------- */
static const char *vr_name(unsigned vr) { return vr < FDI_VR_END ? VARIABLE_NAMES[vr] : "?"; }

int fdi_get(fdi_instance *fi, const char *fn, int kind, unsigned vr, double *value) {
    int have;
    if (vr >= FDI_VR_END) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: no variable has value reference %u", fn, vr);
        return FDI_S_ERROR;
    }
    have = vr >= FDI_VR_OUTPUT0 ? OUTPUT_KINDS[vr - FDI_VR_OUTPUT0] : FDI_KIND_REAL;
    if (have != kind) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: '%s' (value reference %u) is a %s variable, not %s", fn,
                vr_name(vr), vr, KIND_NAMES[have], KIND_NAMES[kind]);
        return FDI_S_ERROR;
    }
    if (vr == FDI_VR_TIME) *value = fi->time;
    else if (vr < FDI_VR_SCALE) *value = fi->inputs[vr - FDI_VR_INPUT0];
    else if (vr == FDI_VR_SCALE) *value = fdi_runtime_threshold_scale(fi->rt);
    else *value = fi->outputs[vr - FDI_VR_OUTPUT0];
    return FDI_S_OK;
}

int fdi_set(fdi_instance *fi, const char *fn, int kind, unsigned vr, double value) {
    if (vr >= FDI_VR_END) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: no variable has value reference %u", fn, vr);
        return FDI_S_ERROR;
    }
    if (vr == FDI_VR_TIME || vr >= FDI_VR_OUTPUT0) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: '%s' (value reference %u) is %s and cannot be set", fn,
                vr_name(vr), vr, vr == FDI_VR_TIME ? "the independent variable" : "an output");
        return FDI_S_ERROR;
    }
    if (kind != FDI_KIND_REAL) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: '%s' (value reference %u) is a Real variable, not %s", fn,
                vr_name(vr), vr, KIND_NAMES[kind]);
        return FDI_S_ERROR;
    }
    if (vr == FDI_VR_SCALE) {
        if (fi->mode != FDI_M_INSTANTIATED && fi->mode != FDI_M_INITIALIZATION && fi->mode != FDI_M_STEP &&
            fi->mode != FDI_M_EVENT) {
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: threshold_scale cannot be set in %s", fn,
                    fdi_mode_name(fi->mode));
            return FDI_S_ERROR;
        }
        if (fdi_runtime_set_threshold_scale(fi->rt, value, fi->why, sizeof fi->why) != FDI_OK) {
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: threshold_scale = %g refused (%s); it stays %g", fn, value,
                    fi->why, fdi_runtime_threshold_scale(fi->rt));
            return FDI_S_ERROR;
        }
        return FDI_S_OK;
    }
    /* an input: any double is accepted; NaN/Inf make the next sample invalid (input_invalid) */
    fi->inputs[vr - FDI_VR_INPUT0] = value;
    return FDI_S_OK;
}

/* ---- step -------------------------------------------------------------------------------- */
int fdi_do_step(fdi_instance *fi, const char *fn, double t, double h) {
    const double *out;
    const size_t nu = fdi_n_u(&FDI_DESIGN);
    int detected, isolated;
    double h_before = fdi_runtime_step(fi->rt), ratio_before = fdi_runtime_sample_ratio(fi->rt);
    fdi_status s;
    if (!isfinite(t) || (isfinite(h) && !isfinite(t + h))) {   /* S9: times are finite (a bad h: Discard) */
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: communication point t=%g with step %g: the time must be a finite "
                "number and stay one (refused, nothing changed)", fn, t, h);
        return FDI_S_ERROR;
    }
    fi->why[0] = 0;
    s = fdi_runtime_advance(fi->rt, fi->inputs, fi->inputs + nu, h, fi->why, sizeof fi->why);
    fi->outputs = fdi_runtime_outputs(fi->rt);
    if (s == FDI_DISCARD) {
        fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "step at t=%g refused: %s", t, fi->why);
        return FDI_S_DISCARD;
    }
    if (s != FDI_OK) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s at t=%.17g: runtime error: %s", fn, t, fi->why);
        fi->mode = FDI_M_ERROR;
        return FDI_S_ERROR;
    }
    fi->time = t + h;
    out = fi->outputs;
    /* the messages and categories of the pythonfmu target (fmu_fdi/fmu/slave_template.py); warnings
     * carry no time: the host knows the call, and identical texts can be counted */
    if (fdi_runtime_sample_ratio(fi->rt) != ratio_before)
        fdi_log(fi, FDI_S_WARNING, FDI_C_WARNING, "step size changed from %g s to %g s (design Ts = %g s): evaluation "
                "windows and thresholds restarted (docs/semantics.md, step sizes)", h_before,
                fdi_runtime_step(fi->rt), fdi_sample_time(&FDI_DESIGN));
    if (out[FDI_IDX_NUMERIC_RESET] != 0.0)
        fdi_log(fi, FDI_S_WARNING, FDI_C_NUMERIC, "the sample overflowed the evaluation (a value became NaN/Inf); "
                "counted as fault evidence, sample discarded, generator and evaluation restarted (numeric_reset, "
                "input_invalid)");
    else if (out[FDI_IDX_INPUT_INVALID] != 0.0)
        fdi_log(fi, FDI_S_WARNING, FDI_C_INPUT, "invalid input sample (NaN/Inf or outside its valid range); "
                "diagnosis held");
    detected = out[FDI_IDX_FAULT_DETECTED] != 0.0;
    isolated = (int)out[FDI_IDX_ISOLATED_FAULT];
    if (detected != fi->last_detected || (detected && isolated != fi->last_isolated)) {
        if (!detected)
            fdi_log(fi, FDI_S_OK, FDI_C_EVENTS, "t=%g: alarm cleared", t);
        else if (isolated > 0 && isolated <= FDI_N_FAULTS)
            fdi_log(fi, FDI_S_OK, FDI_C_EVENTS, "t=%g: fault detected, isolated as '%s'", t, FAULT_NAMES[isolated - 1]);
        else if (isolated < 0)
            fdi_log(fi, FDI_S_OK, FDI_C_EVENTS, "t=%g: fault detected, not isolated (unknown or several faults)", t);
        else
            fdi_log(fi, FDI_S_OK, FDI_C_EVENTS, "t=%g: fault detected", t);
        fi->last_detected = detected;
        fi->last_isolated = isolated;
    }
    return FDI_S_OK;
}

/* ---- FMU state image --------------------------------------------------------------------
 * magic[8] | u64 total | u64 n_inputs | u64 runtime bytes | f64 time | f64 inputs[n] |
 * i32 last_detected | i32 last_isolated | runtime image (fdi_runtime_get_state) |
 * u64 FNV-1a 64 of every byte before it (a flipped bit, byte or truncation changes it) */
#define IMAGE_HEADER (8 + 3 * 8 + 8)
#define IMAGE_TRAILER 8

size_t fdi_image_bytes(const fdi_instance *fi) {
    return IMAGE_HEADER + 8 * (size_t)FDI_N_INPUTS + 8 + fdi_runtime_state_size(fi->rt) + IMAGE_TRAILER;
}

static void put_u64(unsigned char **p, uint64_t v) { memcpy(*p, &v, 8); *p += 8; }
static void put_f64(unsigned char **p, double v) { memcpy(*p, &v, 8); *p += 8; }
static void put_i32(unsigned char **p, int32_t v) { memcpy(*p, &v, 4); *p += 4; }
static uint64_t get_u64(const unsigned char **p) { uint64_t v; memcpy(&v, *p, 8); *p += 8; return v; }
static double get_f64(const unsigned char **p) { double v; memcpy(&v, *p, 8); *p += 8; return v; }
static int32_t get_i32(const unsigned char **p) { int32_t v; memcpy(&v, *p, 4); *p += 4; return v; }

/* FNV-1a 64 (Fowler, Noll, Vo): every step is a bijection of the hash given the byte, so two
 * inputs that differ in one byte always differ in the hash. */
static uint64_t fnv1a64(const unsigned char *p, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= p[i];
        h *= 1099511628211ULL;
    }
    return h;
}

static size_t runtime_image_bytes(size_t len) {
    return len - IMAGE_HEADER - 8 * (size_t)FDI_N_INPUTS - 8 - IMAGE_TRAILER;
}

void fdi_image_get(const fdi_instance *fi, unsigned char *buf) {
    unsigned char *p = buf;
    size_t i, rt = fdi_runtime_state_size(fi->rt), len = fdi_image_bytes(fi);
    memcpy(p, IMAGE_MAGIC, 8);
    p += 8;
    put_u64(&p, len);
    put_u64(&p, FDI_N_INPUTS);
    put_u64(&p, rt);
    put_f64(&p, fi->time);
    for (i = 0; i < FDI_N_INPUTS; i++) put_f64(&p, fi->inputs[i]);
    put_i32(&p, fi->last_detected);
    put_i32(&p, fi->last_isolated);
    fdi_runtime_get_state(fi->rt, p);
    p = buf + len - IMAGE_TRAILER;
    put_u64(&p, fnv1a64(buf, len - IMAGE_TRAILER));
}

int fdi_image_check(fdi_instance *fi, const unsigned char *buf, size_t len, const char *fn) {
    const unsigned char *p = buf + 8;
    uint64_t total, n, rt, sum;
    double t;
    int32_t detected, isolated;
    if (!buf || len < IMAGE_HEADER || memcmp(buf, IMAGE_MAGIC, 8) != 0) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: not an FMU state of an fmu-fdi native FMU (%zu bytes, bad magic)",
                fn, len);
        return FDI_S_ERROR;
    }
    total = get_u64(&p);
    n = get_u64(&p);
    rt = get_u64(&p);
    t = get_f64(&p);
    if (total != len || n != FDI_N_INPUTS || len != fdi_image_bytes(fi) || rt != runtime_image_bytes(len)) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: FMU state of %zu bytes (header: %llu bytes, %llu inputs) does not "
                "fit this FMU (%zu bytes, %d inputs)", fn, len, (unsigned long long)total, (unsigned long long)n,
                fdi_image_bytes(fi), FDI_N_INPUTS);
        return FDI_S_ERROR;
    }
    p = buf + len - IMAGE_TRAILER;
    sum = get_u64(&p);
    if (sum != fnv1a64(buf, len - IMAGE_TRAILER)) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: FMU state checksum mismatch: the bytes were changed after "
                "fmiXSerializeFMUstate wrote them (corrupt copy)", fn);
        return FDI_S_ERROR;
    }
    p = buf + IMAGE_HEADER + 8 * (size_t)FDI_N_INPUTS;
    detected = get_i32(&p);
    isolated = get_i32(&p);
    if (!isfinite(t) || (detected != 0 && detected != 1) || isolated < -1 || isolated > FDI_N_FAULTS) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: FMU state with time %g, logged detection %ld and isolation %ld "
                "(needs a finite time, 0 or 1, and -1..%d)", fn, t, (long)detected, (long)isolated, FDI_N_FAULTS);
        return FDI_S_ERROR;
    }
    return FDI_S_OK;
}

int fdi_image_set(fdi_instance *fi, const unsigned char *buf, size_t len, const char *fn) {
    const unsigned char *p;
    size_t i;
    fdi_status s;
    if (fdi_image_check(fi, buf, len, fn) != FDI_S_OK) return FDI_S_ERROR;
    p = buf + IMAGE_HEADER + 8 * (size_t)FDI_N_INPUTS + 8;
    fi->why[0] = 0;
    s = fdi_runtime_set_state(fi->rt, p, runtime_image_bytes(len), fi->why, sizeof fi->why);
    fi->outputs = fdi_runtime_outputs(fi->rt);
    if (s != FDI_OK) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: FMU state refused: %s (instance unchanged)", fn, fi->why);
        return FDI_S_ERROR;
    }
    p = buf + 8 + 3 * 8;
    fi->time = get_f64(&p);
    for (i = 0; i < FDI_N_INPUTS; i++) fi->inputs[i] = get_f64(&p);
    fi->last_detected = get_i32(&p);
    fi->last_isolated = get_i32(&p);
    return FDI_S_OK;
}

/* ---- FMU state objects handed to the host -------------------------------------------------- */
static fdi_state_obj *as_state(fdi_instance *fi, const char *fn, const void *state) {
    const fdi_state_obj *s = state;
    if (!s || s->magic != STATE_MAGIC) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: %s is not an FMU state of this FMU (or was freed)", fn,
                s ? "the pointer" : "NULL");
        return NULL;
    }
    return (fdi_state_obj *)state;
}

static fdi_state_obj *new_state(fdi_instance *fi, const char *fn, size_t len) {
    fdi_state_obj *s = fi->alloc(fi->host, sizeof(fdi_state_obj) + len);
    if (!s) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: out of memory for an FMU state of %zu bytes", fn, len);
        return NULL;
    }
    s->magic = STATE_MAGIC;
    s->owner = fi;
    s->len = len;
    return s;
}

int fdi_state_get(fdi_instance *fi, const char *fn, void **state) {
    size_t len = fdi_image_bytes(fi);
    fdi_state_obj *s;
    if (!state) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: NULL pointer for the state", fn);
        return FDI_S_ERROR;
    }
    if (*state) {  /* overwrite a state this FMU gave out earlier */
        if (!(s = as_state(fi, fn, *state))) return FDI_S_ERROR;
        if (s->len != len) {
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: the state to overwrite holds %zu bytes, this instance needs %zu",
                    fn, s->len, len);
            return FDI_S_ERROR;
        }
    } else if (!(s = new_state(fi, fn, len))) {
        return FDI_S_ERROR;
    }
    fdi_image_get(fi, s->data);
    *state = s;
    fdi_log(fi, FDI_S_OK, FDI_C_STATE, "%s: FMU state saved at t=%g (%zu bytes)", fn, fi->time, len);
    return FDI_S_OK;
}

int fdi_state_set(fdi_instance *fi, const char *fn, const void *state) {
    fdi_state_obj *s = as_state(fi, fn, state);
    if (!s || fdi_image_set(fi, s->data, s->len, fn) != FDI_S_OK) return FDI_S_ERROR;
    fdi_log(fi, FDI_S_OK, FDI_C_STATE, "%s: FMU state restored, t=%g", fn, fi->time);
    return FDI_S_OK;
}

int fdi_state_free(fdi_instance *fi, const char *fn, void **state) {
    fdi_state_obj *s;
    if (!state || !*state) return FDI_S_OK;  /* freeing nothing is allowed */
    if (!(s = as_state(fi, fn, *state))) return FDI_S_ERROR;
    s->magic = 0;
    fi->release(fi->host, s);
    *state = NULL;
    return FDI_S_OK;
}

int fdi_state_size(fdi_instance *fi, const char *fn, const void *state, size_t *size) {
    fdi_state_obj *s = as_state(fi, fn, state);
    if (!s) return FDI_S_ERROR;
    if (!size) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: NULL pointer for the size", fn);
        return FDI_S_ERROR;
    }
    *size = s->len;
    return FDI_S_OK;
}

int fdi_state_serialize(fdi_instance *fi, const char *fn, const void *state, unsigned char *buf, size_t size) {
    fdi_state_obj *s = as_state(fi, fn, state);
    if (!s) return FDI_S_ERROR;
    if (!buf || size != s->len) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: buffer of %zu bytes for a state of %zu bytes", fn, buf ? size : 0,
                s->len);
        return FDI_S_ERROR;
    }
    memcpy(buf, s->data, s->len);
    return FDI_S_OK;
}

int fdi_state_deserialize(fdi_instance *fi, const char *fn, const unsigned char *buf, size_t size, void **state) {
    fdi_state_obj *s;
    if (!state) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: NULL pointer for the state", fn);
        return FDI_S_ERROR;
    }
    if (fdi_image_check(fi, buf, size, fn) != FDI_S_OK) return FDI_S_ERROR;
    if (*state) {
        if (!(s = as_state(fi, fn, *state))) return FDI_S_ERROR;
        if (s->len != size) {
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: the state to overwrite holds %zu bytes, the data %zu", fn,
                    s->len, size);
            return FDI_S_ERROR;
        }
    } else if (!(s = new_state(fi, fn, size))) {
        return FDI_S_ERROR;
    }
    memcpy(s->data, buf, size);
    *state = s;
    return FDI_S_OK;
}
