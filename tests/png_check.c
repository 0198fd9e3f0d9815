/* png_check - the pixel checks of tests/view.sh: reads an 8-bit RGB PNG
 * (as simcluster-view writes them) and prints what the test asserts on.
 * Usage: png_check FILE W H SKY_R,SKY_G,SKY_B
 * Prints one line: "colours N nonsky F centre R G B CLASS" where N is the
 * number of distinct colours, F the fraction of pixels that are not the
 * sky colour, and CLASS the centre pixel's: sky (the clear colour, +-2),
 * grey (the floor: channels within 24 of each other) or body (saturated:
 * simcluster-view colours bodies by state with strong hues). Exit 0, or 1
 * when the file is not such a PNG of W x H (one line on stderr). */
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    unsigned sky[3];
    if (argc != 5 || sscanf(argv[4], "%u,%u,%u", &sky[0], &sky[1], &sky[2]) != 3) {
        fprintf(stderr, "usage: png_check FILE W H R,G,B\n");
        return 2;
    }
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, argv[1])) {
        fprintf(stderr, "png_check: %s: %s\n", argv[1], im.message);
        return 1;
    }
    im.format = PNG_FORMAT_RGB;
    if (im.width != (png_uint_32)atol(argv[2]) || im.height != (png_uint_32)atol(argv[3])) {
        fprintf(stderr, "png_check: %s: %ux%u, expected %sx%s\n", argv[1], (unsigned)im.width,
                (unsigned)im.height, argv[2], argv[3]);
        png_image_free(&im);
        return 1;
    }
    size_t n = (size_t)im.width * im.height;
    unsigned char *px = malloc(3 * n);
    unsigned char *seen = calloc(1u << 21, 1);     /* 24-bit colours, one bit each */
    if (!px || !seen || !png_image_finish_read(&im, NULL, px, 0, NULL)) {
        fprintf(stderr, "png_check: %s: %s\n", argv[1], px && seen ? im.message : "no memory");
        free(px);
        free(seen);
        return 1;
    }
    size_t colours = 0, nonsky = 0;
    for (size_t i = 0; i < n; i++) {
        const unsigned char *p = px + 3 * i;
        unsigned c = (unsigned)p[0] << 16 | (unsigned)p[1] << 8 | p[2];
        if (!(seen[c >> 3] & 1u << (c & 7))) {
            seen[c >> 3] |= (unsigned char)(1u << (c & 7));
            colours++;
        }
        nonsky += abs(p[0] - (int)sky[0]) > 2 || abs(p[1] - (int)sky[1]) > 2 ||
                  abs(p[2] - (int)sky[2]) > 2;
    }
    const unsigned char *c = px + 3 * ((size_t)(im.height / 2) * im.width + im.width / 2);
    int lo = c[0], hi = c[0];
    for (int k = 1; k < 3; k++) {
        lo = c[k] < lo ? c[k] : lo;
        hi = c[k] > hi ? c[k] : hi;
    }
    int is_sky = abs(c[0] - (int)sky[0]) <= 2 && abs(c[1] - (int)sky[1]) <= 2 &&
                 abs(c[2] - (int)sky[2]) <= 2;
    printf("colours %zu nonsky %.4f centre %d %d %d %s\n", colours, (double)nonsky / (double)n,
           c[0], c[1], c[2], is_sky ? "sky" : hi - lo < 24 ? "grey" : "body");
    free(px);
    free(seen);
    return 0;
}
