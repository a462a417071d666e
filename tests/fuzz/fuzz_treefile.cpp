// Tree files: any bytes are loaded as a .qota file; a file that loads must answer queries.
#include <variant>

#include "fuzz_common.hpp"
#include "qota/error.hpp"
#include "qota/treefile.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = qota::fuzz::writeFile("input.qota", data, size);
  try {
    const qota::TreeFile tf = qota::loadTree(path);
    std::visit(
        [](const auto& index) {
          const qota::Box2 box = index.tree().box();
          for (int i = 0; i <= 4; ++i) {
            const double u = box.ulo + (box.uhi - box.ulo) * i / 4, v = box.vlo + (box.vhi - box.vlo) * (4 - i) / 4;
            (void)index.top(u, v);
            (void)index.below(u, v, 0.0);
            (void)index.all(u, v);
          }
          (void)index.stats();
        },
        tf.index);
  } catch (const qota::Error&) {
  }
  return 0;
}
