/* island.c - contact-graph islands (the paper's "extracting the contact
 * graph"): union-find over the contacts of awake dynamic bodies. Static and
 * sleeping bodies do not join islands, so a floor does not merge every pile
 * into one LCP. Output is canonical: islands ordered by their smallest body
 * id, bodies ascending, contacts in the (canonical) contact order. */
#include <stdlib.h>
#include <string.h>

#include "core.h"

int sc_uf_find(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];   /* path halving */
        i = parent[i];
    }
    return i;
}

void sc_uf_unite(int *parent, int a, int b)
{
    a = sc_uf_find(parent, a);
    b = sc_uf_find(parent, b);
    /* the smaller id becomes the root: roots are then canonical */
    if (a < b)
        parent[b] = a;
    else if (b < a)
        parent[a] = b;
}

void sc_islands_free(sc_islands *is)
{
    if (!is)
        return;
    free(is->body_start);
    free(is->bodies);
    free(is->contact_start);
    free(is->contacts);
    memset(is, 0, sizeof *is);
}

/* Room for nbodies and ncontacts in is (kept between builds). */
static int reserve(sc_islands *is, int nbodies, int ncontacts)
{
    if (nbodies > is->body_cap || !is->body_start) {
        int cap = nbodies > 2 * is->body_cap ? nbodies : 2 * is->body_cap;
        cap = cap > 0 ? cap : 1;
        int *bs = sc_alloc_array((size_t)cap + 1, sizeof *bs);
        int *b = sc_alloc_array((size_t)cap, sizeof *b);
        int *cs = sc_alloc_array((size_t)cap + 1, sizeof *cs);
        if (!bs || !b || !cs) {
            free(bs);
            free(b);
            free(cs);
            return SC_ENOMEM;
        }
        free(is->body_start);
        free(is->bodies);
        free(is->contact_start);
        is->body_start = bs;
        is->bodies = b;
        is->contact_start = cs;
        is->body_cap = cap;
    }
    if (ncontacts > is->contact_cap || !is->contacts) {
        int cap = ncontacts > 2 * is->contact_cap ? ncontacts : 2 * is->contact_cap;
        cap = cap > 0 ? cap : 1;
        int *c = sc_alloc_array((size_t)cap, sizeof *c);
        if (!c)
            return SC_ENOMEM;
        free(is->contacts);
        is->contacts = c;
        is->contact_cap = cap;
    }
    return SC_OK;
}

int sc_islands_build(sc_arena *arena, int nbodies, const unsigned char *joins,
                     const sc_contact *c, int ncontacts, sc_islands *is)
{
    if (nbodies < 0 || ncontacts < 0 || (!joins && (nbodies || ncontacts)) || !is || (ncontacts && !c))
        return SC_EINVAL;
    is->count = 0;
    if (reserve(is, nbodies, ncontacts) != SC_OK)
        return SC_ENOMEM;
    memset(is->body_start, 0, ((size_t)nbodies + 1) * sizeof *is->body_start);
    memset(is->contact_start, 0, ((size_t)nbodies + 1) * sizeof *is->contact_start);
    int *parent = sc_arena_alloc(arena, (size_t)nbodies * sizeof *parent);
    int *slot = parent ? sc_arena_alloc(arena, (size_t)nbodies * sizeof *slot) : NULL;
    int rc = SC_ENOMEM;
    if (!slot)
        goto out;
    for (int i = 0; i < nbodies; i++)
        parent[i] = i;
    for (int k = 0; k < ncontacts; k++) {
        int a = c[k].body_a, b = c[k].body_b;
        if (a < 0 || b < 0 || a >= nbodies || b >= nbodies) {
            rc = SC_EINVAL;
            goto out;
        }
        if (joins[a] && joins[b])
            sc_uf_unite(parent, a, b);
    }
    /* number islands by first appearance of their root in id order */
    int n = 0;
    for (int i = 0; i < nbodies; i++)
        slot[i] = -1;
    for (int i = 0; i < nbodies; i++) {
        if (!joins[i])
            continue;
        int r = sc_uf_find(parent, i);
        if (slot[r] < 0)
            slot[r] = n++;
        is->body_start[slot[r] + 1]++;
    }
    /* an island's contacts: those touching one of its bodies */
    for (int k = 0; k < ncontacts; k++) {
        int a = c[k].body_a, b = c[k].body_b;
        int owner = joins[a] ? a : (joins[b] ? b : -1);
        if (owner >= 0)
            is->contact_start[slot[sc_uf_find(parent, owner)] + 1]++;
    }
    for (int i = 0; i < n; i++) {
        is->body_start[i + 1] += is->body_start[i];
        is->contact_start[i + 1] += is->contact_start[i];
    }
    /* island of each body; then parent's storage becomes the fill cursor */
    for (int i = 0; i < nbodies; i++)
        if (joins[i])
            parent[i] = sc_uf_find(parent, i);
    for (int i = 0; i < nbodies; i++)
        slot[i] = joins[i] ? slot[parent[i]] : -1;   /* roots come first: r <= i */
    int *root_of = slot, *fill = parent;
    for (int i = 0; i < n; i++)
        fill[i] = is->body_start[i];
    for (int i = 0; i < nbodies; i++)
        if (root_of[i] >= 0)
            is->bodies[fill[root_of[i]]++] = i;
    for (int i = 0; i < n; i++)
        fill[i] = is->contact_start[i];
    for (int k = 0; k < ncontacts; k++) {
        int a = c[k].body_a, b = c[k].body_b;
        int owner = joins[a] ? a : (joins[b] ? b : -1);
        if (owner >= 0)
            is->contacts[fill[root_of[owner]]++] = k;
    }
    is->count = n;
    rc = SC_OK;
out:
    sc_arena_free(arena, slot);
    sc_arena_free(arena, parent);
    if (rc != SC_OK)
        is->count = 0;
    return rc;
}
