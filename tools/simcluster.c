/* simcluster - the command-line tool (simcluster(1)). This release has
 * one command: keygen, the cluster key every daemon and master shares.
 * The others (run, profile, lcp) come with the tools issue. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "cluster_msg.h"
#include "simcluster.h"

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: simcluster keygen FILE   write a new cluster key (mode 0600)\n"
               "       simcluster --help\n");
    return status;
}

static int keygen(int argc, char **argv)
{
    if (argc != 3 || argv[2][0] == '\0')
        return usage(stderr, 2);
    int rc = sc_key_generate(argv[2]);
    if (rc != SC_OK) {
        /* sc_key_generate never overwrites: say which case it was */
        const char *why = rc == SC_EIO && errno == EEXIST ? "the file exists (never overwritten)"
                          : rc == SC_EIO                  ? strerror(errno)
                                                          : sc_strerror(rc);
        fprintf(stderr, "simcluster: keygen: %s: %s\n", argv[2], why);
        return 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 2)
        return usage(stderr, 2);
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))
        return usage(stdout, 0);
    if (!strcmp(argv[1], "keygen"))
        return keygen(argc, argv);
    fprintf(stderr, "simcluster: unknown command '%s' (try simcluster --help)\n", argv[1]);
    return 2;
}
