/* ASan/UBSan driver for benchmarks/fuzz/interpolator_asan.py: load and replay every
 * (path file, profile file) pair listed in the file argv[1]. */
#include <stdio.h>
#include <string.h>
#include "interp_path.h"
int main(int argc, char **argv) {
    FILE *f = fopen(argv[1], "r");
    char p[4096], q[4096], err[1024];
    long ok = 0, bad = 0;
    while (fscanf(f, "%4095s %4095s", p, q) == 2) {
        Track *t = track_load(p, q, 250e-6, err, sizeof err);
        if (t) {
            double x[3], u = 0, r; long h = 0;
            for (long k = 0; k < t->nrows; k++) track_point(t, t->ps[k], x, &u, &h, &r);
            track_free(t); ok++;
        } else bad++;
    }
    printf("ok %ld error %ld\n", ok, bad);
    return 0;
}
