/*
 * wcet_insn.c - QEMU TCG plugin: exact guest-instruction counts between
 * marker instructions, per call.  From the project's WCET recipe
 * (firmware/wcet/README.md); built and run by firmware/wcet/measure.sh, which
 * uses regions 0..2 = dynamics, self_collision, projection (src/bin/wcet.rs).  Self-contained (declares the few plugin
 * API symbols it uses, API v1 as in QEMU 7.2, so no qemu-plugin.h needed).
 *
 * Markers (Thumb-2 DBG hint = NOP on real Cortex-M and in QEMU):
 *     dbg #(2*r)     begin region r   (r = 0..7)
 *     dbg #(2*r+1)   end   region r
 * A region's count = instructions executed strictly between the two markers
 * (everything called from inside it included; markers themselves excluded).
 *
 * Arguments (-plugin ./wcet_insn.so,arg=val,...):
 *     out=FILE   write results there (default stderr)
 *     each=on    print every sample, not only the summary   (default on)
 *     hist=on    per-region histogram of executed mnemonics  (default off)
 *     model=m4   also report a [lo, hi] cycle ESTIMATE per call from a
 *                Cortex-M4 timing table (TRM-style: loads 1-2, taken branch
 *                +1..3, LDM/STM/PUSH/POP 1+N, VDIV/VSQRT 14, VMLA 3, DIV 2-12).
 *                Zero-wait-state memory, no stalls from flash/bus/IRQs:
 *                a model, not a measurement.  Meaningless for Cortex-M7.
 *
 * Build: gcc -O2 -shared -fPIC -o wcet_insn.so wcet_insn.c          (QEMU 7.x, API v1)
 *        gcc -O2 -shared -fPIC -DQEMU_PLUGIN_API_VERSION=3 ...       (QEMU 9.x/10.x)
 * Run:   qemu-system-arm ... -plugin ./wcet_insn.so,out=counts.txt
 * (No -d plugin needed: results are written with stdio, not qemu_plugin_outs.)
 *
 * Every sample line also reports fp_div_sqrt=<n>: the VDIV and VSQRT instructions executed
 * in the region (14 cycles each on the Cortex-M4 and M7, where most instructions take one),
 * so a cycle estimate can charge their latency.
 *
 * Counting uses per-instruction exec callbacks (not TB-level counts), which
 * stays exact when a TB is cut short (I/O under -icount, exceptions).
 */
#define _GNU_SOURCE
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qemu_plugin_api.h"

#define NREG 8
#define MAXMN 1024

static uint64_t total;                 /* all guest insns executed */
static uint64_t slow;                  /* VDIV/VSQRT executed (all of them) */
static uint64_t start[NREG], slow_start[NREG];
static int depth[NREG];                /* >0 while inside region r */
static int inside;                     /* number of open regions */
static struct { uint64_t n, min, max, sum; } st[NREG];
static FILE *out;
static bool each = true, hist = false, model = false;

/* cycle model accumulators (global; regions take differences) */
static uint64_t cyc_lo, cyc_hi, cstart_lo[NREG], cstart_hi[NREG];
static struct { uint64_t min, max; } cst_lo[NREG], cst_hi[NREG];

typedef struct {
    uint64_t vaddr, fallthrough;
    uint16_t lo, hi;          /* cycles if not a taken branch */
    uint8_t branch;           /* may change control flow */
    uint8_t tlo, thi;         /* extra cycles when taken (pipeline refill P) */
    uint8_t slow;             /* VDIV or VSQRT */
    int mn;                   /* mnemonic index (hist) */
} insn_info;
static const insn_info *pending;   /* last executed branch, resolved by the next insn */

/* mnemonic histogram: table of names, counts per region */
static char *mn_name[MAXMN];
static int n_mn;
static uint64_t mn_count[NREG][MAXMN];

static int mn_index(const char *disas)
{
    char m[32];
    size_t i = 0;
    while (disas[i] && disas[i] != ' ' && disas[i] != '\t' && i < sizeof(m) - 1) {
        m[i] = disas[i];
        i++;
    }
    m[i] = 0;
    for (int k = 0; k < n_mn; k++) {
        if (strcmp(mn_name[k], m) == 0) {
            return k;
        }
    }
    if (n_mn == MAXMN) {
        return MAXMN - 1;
    }
    mn_name[n_mn] = strdup(m);
    return n_mn++;
}

static void count_cb(unsigned int vcpu, void *udata)
{
    (void)vcpu;
    total++;
}

/* VDIV / VSQRT (single or double precision) */
static bool is_div_sqrt(const char *disas)
{
    return strncmp(disas, "vdiv", 4) == 0 || strncmp(disas, "vsqrt", 5) == 0;
}

/* taken-branch penalty of the previous instruction, now that we know where we went */
static inline void resolve_pending(uint64_t vaddr)
{
    if (pending) {
        if (vaddr != pending->fallthrough) {
            cyc_lo += pending->tlo;
            cyc_hi += pending->thi;
        }
        pending = NULL;
    }
}

static void info_cb(unsigned int vcpu, void *udata)
{
    (void)vcpu;
    const insn_info *in = udata;
    total++;
    slow += in->slow;
    resolve_pending(in->vaddr);
    cyc_lo += in->lo;
    cyc_hi += in->hi;
    if (in->branch) {
        pending = in;
    }
    if (hist && inside) {
        for (int r = 0; r < NREG; r++) {
            if (depth[r]) {
                mn_count[r][in->mn]++;
            }
        }
    }
}

/* ---- Cortex-M4 timing table (approximate; see header) ------------------ */
static int nregs(const char *d)
{
    const char *b = strchr(d, '{'), *e = b ? strchr(b, '}') : NULL;
    if (!b || !e) return 1;
    int n = 1;
    for (const char *p = b; p < e; p++) if (*p == ',') n++;
    return n;
}

static bool has(const char *d, const char *w) { return strstr(d, w) != NULL; }
static bool is(const char *m, const char *p) { return strncmp(m, p, strlen(p)) == 0; }

/* b, b<cond>, b.w, b<cond>.w, bl, blx, bx, cbz, cbnz, tbb, tbh */
static bool is_branch(const char *m)
{
    static const char *cc[] = {"eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs",
                               "vc", "hi", "ls", "ge", "lt", "gt", "le", "al", NULL};
    if (!strcmp(m, "bl") || !strcmp(m, "blx") || !strcmp(m, "bx") || is(m, "cbz") ||
        is(m, "cbnz") || is(m, "tbb") || is(m, "tbh")) return true;
    if (m[0] != 'b') return false;
    const char *r = m + 1;
    for (int i = 0; cc[i]; i++) {
        if (!strncmp(r, cc[i], 2)) { r += 2; break; }
    }
    return *r == 0 || !strcmp(r, ".w") || !strcmp(r, ".n");
}

static void m4_cost(const char *m, const char *d, insn_info *in)
{
    in->lo = in->hi = 1;
    in->branch = 0;
    in->tlo = 1; in->thi = 3;                      /* P = 1..3 */
    bool pc_dest = false;
    {   /* first operand is pc? (mov pc / ldr pc / add pc ...) */
        const char *a = strchr(d, ' ');
        while (a && *a == ' ') a++;
        if (a && strncmp(a, "pc", 2) == 0) pc_dest = true;
    }
    if (is_branch(m)) {
        in->branch = 1;
        if (is(m, "tbb") || is(m, "tbh")) { in->lo = in->hi = 2; }   /* table load */
    } else if (is(m, "vpush") || is(m, "vpop") || is(m, "vldm") || is(m, "vstm")) {
        int n = nregs(d), w = has(d, "{d") ? 2 * n : n;
        in->lo = 1 + n; in->hi = 1 + w;
    } else if (is(m, "push") || is(m, "pop") || is(m, "ldm") || is(m, "stm")) {
        int n = nregs(d);
        in->lo = in->hi = 1 + n;
        if ((is(m, "pop") || is(m, "ldm")) && has(d, "pc")) in->branch = 1;
    } else if (is(m, "ldrd") || is(m, "strd")) {
        in->lo = 2; in->hi = 3;
    } else if (is(m, "vldr") || is(m, "vstr")) {
        bool dbl = has(d, " d");
        in->lo = dbl ? 2 : 1; in->hi = dbl ? 3 : 2;
    } else if (is(m, "ldr") || is(m, "str")) {
        in->lo = 1; in->hi = 2;                    /* pipelined neighbours: 1 */
        if (is(m, "ldr") && pc_dest) in->branch = 1;
    } else if (is(m, "sdiv") || is(m, "udiv")) {
        in->lo = 2; in->hi = 12;
    } else if (is(m, "mla") || is(m, "mls")) {
        in->lo = in->hi = 2;
    } else if (is(m, "vdiv") || is(m, "vsqrt")) {
        in->lo = in->hi = 14;
    } else if (is(m, "vmla") || is(m, "vmls") || is(m, "vnmla") || is(m, "vnmls") || is(m, "vfma") ||
               is(m, "vfms") || is(m, "vfnma") || is(m, "vfnms")) {
        in->lo = in->hi = 3;
    } else if (is(m, "vmov") && (has(d, "r") && (has(d, " d") || nregs(d) > 1 || has(d, ", s") + has(d, " s") > 1))) {
        in->lo = 1; in->hi = 2;                    /* core<->FP register pairs */
    } else if (is(m, "it")) {
        in->lo = 0; in->hi = 1;                    /* IT often folds */
    } else if (is(m, "isb") || is(m, "dsb") || is(m, "dmb")) {
        in->lo = 1; in->hi = 4;
    } else if (pc_dest) {
        in->branch = 1;
    }
    /* a branch costs lo/hi itself, plus tlo/thi (pipeline refill) when taken */
}

static void marker_cb(unsigned int vcpu, void *udata)
{
    (void)vcpu;
    const insn_info *in = udata;
    int code = in->mn, r = code >> 1;
    total++;
    resolve_pending(in->vaddr);
    if ((code & 1) == 0) {                  /* begin */
        start[r] = total;                   /* first insn after the marker */
        slow_start[r] = slow;
        cstart_lo[r] = cyc_lo;
        cstart_hi[r] = cyc_hi;
        depth[r] = 1;
        inside++;
    } else if (depth[r]) {                  /* end */
        uint64_t d = total - 1 - start[r];  /* exclude the end marker */
        uint64_t lo = cyc_lo - cstart_lo[r], hi = cyc_hi - cstart_hi[r];
        depth[r] = 0;
        inside--;
        if (st[r].n == 0 || d < st[r].min) st[r].min = d;
        if (d > st[r].max) st[r].max = d;
        if (st[r].n == 0 || lo < cst_lo[r].min) cst_lo[r].min = lo;
        if (lo > cst_lo[r].max) cst_lo[r].max = lo;
        if (st[r].n == 0 || hi < cst_hi[r].min) cst_hi[r].min = hi;
        if (hi > cst_hi[r].max) cst_hi[r].max = hi;
        st[r].sum += d;
        st[r].n++;
        if (each) {
            fprintf(out, "wcet region=%d sample=%llu insns=%llu fp_div_sqrt=%llu", r,
                    (unsigned long long)st[r].n - 1, (unsigned long long)d,
                    (unsigned long long)(slow - slow_start[r]));
            if (model) {
                fprintf(out, " m4_cycles_est=[%llu, %llu]", (unsigned long long)lo,
                        (unsigned long long)hi);
            }
            fprintf(out, "\n");
        }
    }
}

/* Thumb-2 DBG #imm4: halfwords 0xF3AF, 0x80F0|imm4 */
static int dbg_code(struct qemu_plugin_insn *insn)
{
    if (qemu_plugin_insn_size(insn) != 4) {
        return -1;
    }
#if QEMU_PLUGIN_API_VERSION >= 3
    uint8_t b[4];
    if (qemu_plugin_insn_data(insn, b, 4) != 4) {
        return -1;
    }
#else
    const uint8_t *b = qemu_plugin_insn_data(insn);
#endif
    uint16_t h0 = b[0] | (b[1] << 8), h1 = b[2] | (b[3] << 8);
    if (h0 == 0xF3AF && (h1 & 0xFFF0) == 0x80F0) {
        return h1 & 0xF;
    }
    return -1;
}

static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        int code = dbg_code(insn);
        char *d = code < 0 ? qemu_plugin_insn_disas(insn) : NULL;
        const char *ds = d ? d : "?";
        bool div_sqrt = is_div_sqrt(ds);
        if (code < 0 && !hist && !model && !div_sqrt) {
            free(d);
            qemu_plugin_register_vcpu_insn_exec_cb(insn, count_cb, QEMU_PLUGIN_CB_NO_REGS, NULL);
            continue;
        }
        /* one small record per translated insn (TBs are translated once) */
        insn_info *in = calloc(1, sizeof(*in));
        in->vaddr = qemu_plugin_insn_vaddr(insn);
        in->fallthrough = in->vaddr + qemu_plugin_insn_size(insn);
        if (code >= 0) {
            in->mn = code;
            in->lo = in->hi = 1;
            qemu_plugin_register_vcpu_insn_exec_cb(insn, marker_cb, QEMU_PLUGIN_CB_NO_REGS, in);
            continue;
        }
        in->slow = div_sqrt;
        char m[32];
        size_t k = 0;
        while (ds[k] && ds[k] != ' ' && k < sizeof(m) - 1) { m[k] = ds[k]; k++; }
        m[k] = 0;
        if (hist) in->mn = mn_index(ds);
        if (model) m4_cost(m, ds, in);
        free(d);
        qemu_plugin_register_vcpu_insn_exec_cb(insn, info_cb, QEMU_PLUGIN_CB_NO_REGS, in);
    }
}

static int cmp_desc(const void *a, const void *b, void *ctx)
{
    const uint64_t *c = ctx;
    int x = *(const int *)a, y = *(const int *)b;
    return c[y] > c[x] ? 1 : c[y] < c[x] ? -1 : 0;
}

static void at_exit(qemu_plugin_id_t id, void *p)
{
    (void)id; (void)p;
    for (int r = 0; r < NREG; r++) {
        if (!st[r].n) {
            continue;
        }
        fprintf(out, "wcet SUMMARY region=%d samples=%llu min=%llu max=%llu mean=%.1f spread=%llu\n",
                r, (unsigned long long)st[r].n, (unsigned long long)st[r].min,
                (unsigned long long)st[r].max, (double)st[r].sum / st[r].n,
                (unsigned long long)(st[r].max - st[r].min));
        if (model) {
            fprintf(out, "wcet MODEL region=%d m4_cycles_est lo: min=%llu max=%llu  hi: min=%llu max=%llu"
                    "  (cycles/insn at max: %.2f..%.2f)\n", r,
                    (unsigned long long)cst_lo[r].min, (unsigned long long)cst_lo[r].max,
                    (unsigned long long)cst_hi[r].min, (unsigned long long)cst_hi[r].max,
                    (double)cst_lo[r].max / st[r].max, (double)cst_hi[r].max / st[r].max);
        }
        if (hist) {
            int idx[MAXMN];
            for (int k = 0; k < n_mn; k++) idx[k] = k;
            qsort_r(idx, n_mn, sizeof(int), cmp_desc, mn_count[r]);
            fprintf(out, "wcet HIST region=%d (all samples together):", r);
            for (int k = 0; k < n_mn && mn_count[r][idx[k]]; k++) {
                fprintf(out, " %s=%llu", mn_name[idx[k]], (unsigned long long)mn_count[r][idx[k]]);
            }
            fprintf(out, "\n");
        }
    }
    fprintf(out, "wcet total guest insns=%llu\n", (unsigned long long)total);
    fflush(out);
}

EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv)
{
    (void)info;
    out = stderr;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            out = fopen(argv[i] + 4, "w");
            if (!out) {
                perror(argv[i] + 4);
                return -1;
            }
            /* Each sample line is in the file when its region ends: a PIL run reads the file
             * while QEMU runs, and QEMU may be killed rather than exit. */
            setvbuf(out, NULL, _IOLBF, 0);
        } else if (strcmp(argv[i], "each=off") == 0) {
            each = false;
        } else if (strcmp(argv[i], "hist=on") == 0) {
            hist = true;
        } else if (strcmp(argv[i], "model=m4") == 0) {
            model = true;
        } else if (strcmp(argv[i], "each=on") && strcmp(argv[i], "hist=off") &&
                   strcmp(argv[i], "model=off")) {
            fprintf(stderr, "wcet_insn: unknown argument %s\n", argv[i]);
            return -1;
        }
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, tb_trans);
    qemu_plugin_register_atexit_cb(id, at_exit, NULL);
    return 0;
}
