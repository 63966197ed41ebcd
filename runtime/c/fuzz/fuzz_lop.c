/* libFuzzer target for lop.h: every input is opened as a whole file and as a prefix; whatever
   opens is used with every query and decode (tests/exercise.h). Crashes, sanitizer reports and
   leaks are findings. Built with FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION: checksums are not compared,
   so that mutations reach the JSON parser, the validator and the decoders. Seeds: the .lop files of fixtures/conformance.

     make -C runtime/c fuzz && build/fuzz/fuzz_lop -max_total_time=60 CORPUS_DIR ../../fixtures/conformance
*/
#define LOP_IMPLEMENTATION
#include "../lop.h"
#include "../tests/exercise.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    int prefix;
    for (prefix = 0; prefix < 2; prefix++) {
        lop_options opt;
        lop_file *f = NULL;
        lop_message msg;
        memset(&opt, 0, sizeof opt);
        opt.allow_prefix = prefix;
        if (lop_open(data, size, &opt, &f, &msg) == lop_success) {
            lop_exercise(f, 1);
            lop_close(f);
        } else if (f != NULL || msg.text[0] == 0) {
            __builtin_trap(); /* a failure must leave no file and say why */
        }
    }
    return 0;
}
