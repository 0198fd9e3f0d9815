/* replay_main.c - a main() for fuzz targets built without libFuzzer: runs
 * LLVMFuzzerTestOneInput once on every file named on the command line, and
 * on every file in a directory named there (one level, in name order), then
 * prints "replayed N inputs". Exits 1 if a file cannot be read. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Reads path whole and feeds it to the target; 0 on success. */
static int replay_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        return -1;
    }
    size_t cap = 4096, n = 0;
    uint8_t *buf = malloc(cap);
    while (buf) {
        n += fread(buf + n, 1, cap - n, f);
        if (n < cap)
            break;
        uint8_t *nb = realloc(buf, 2 * cap);
        if (!nb) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = nb;
        cap *= 2;
    }
    int bad = !buf || ferror(f);
    fclose(f);
    if (bad) {
        fprintf(stderr, "%s: cannot read\n", path);
        free(buf);
        return -1;
    }
    LLVMFuzzerTestOneInput(buf, n);
    free(buf);
    return 0;
}

int main(int argc, char **argv)
{
    long replayed = 0;
    int rc = 0;
    for (int i = 1; i < argc; i++) {
        struct stat st;
        if (stat(argv[i], &st) != 0) {
            perror(argv[i]);
            rc = 1;
            continue;
        }
        if (!S_ISDIR(st.st_mode)) {
            if (replay_file(argv[i]) == 0)
                replayed++;
            else
                rc = 1;
            continue;
        }
        struct dirent **ent;
        int n = scandir(argv[i], &ent, NULL, alphasort);
        if (n < 0) {
            perror(argv[i]);
            rc = 1;
            continue;
        }
        for (int j = 0; j < n; j++) {
            char path[4096];
            int len = snprintf(path, sizeof path, "%s/%s", argv[i], ent[j]->d_name);
            struct stat es;
            /* files only: one level deep, and . and .. are directories */
            if (len > 0 && (size_t)len < sizeof path && stat(path, &es) == 0 &&
                S_ISREG(es.st_mode)) {
                if (replay_file(path) == 0)
                    replayed++;
                else
                    rc = 1;
            }
            free(ent[j]);
        }
        free(ent);
    }
    printf("replayed %ld inputs\n", replayed);
    return rc;
}
