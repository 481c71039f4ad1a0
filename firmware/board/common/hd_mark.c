/* hd_mark: see hd_mark.h.  Each marker is one `bx lr` at its own address;
 * written in assembly so no compiler merges them. */
#include "hd_mark.h"

__asm__(".section .text.hd_mark,\"ax\",%progbits\n"
        ".balign 4\n"
        ".global hd_mark_begin\n.type hd_mark_begin,%function\n.thumb_func\n"
        "hd_mark_begin: bx lr\n.size hd_mark_begin,.-hd_mark_begin\n"
        ".global hd_mark_end\n.type hd_mark_end,%function\n.thumb_func\n"
        "hd_mark_end: bx lr\n.size hd_mark_end,.-hd_mark_end\n"
        ".global hd_mark_section\n.type hd_mark_section,%function\n.thumb_func\n"
        "hd_mark_section: bx lr\n.size hd_mark_section,.-hd_mark_section\n"
        ".global hd_bench_loop\n.type hd_bench_loop,%function\n.thumb_func\n"
        "hd_bench_loop: subs r0, r0, #1\n bne hd_bench_loop\n bx lr\n"
        ".size hd_bench_loop,.-hd_bench_loop\n"
        ".text\n");

void hd_mark_calibration(void (*section)(const char *label))
{
    section("empty:-");
    for (unsigned i = 0; i < 16u; i++) {
        hd_mark_begin();
        hd_mark_end();
    }
    hd_mark_section();
    section("loop:-");
    hd_mark_begin();
    hd_bench_loop(10u);
    hd_mark_end();
    hd_mark_begin();
    hd_bench_loop(1010u);
    hd_mark_end();
    hd_mark_section();
}
