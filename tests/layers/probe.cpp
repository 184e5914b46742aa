// Includes the header a layering test names (tests/CMakeLists.txt). Built
// against one layer's library, it must fail to build when the header
// belongs to a layer that library does not link.
#include CES_PROBE_HEADER
