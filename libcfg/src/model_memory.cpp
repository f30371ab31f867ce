#include "cfg/model_memory.hpp"

#include <sys/mman.h>

#include <algorithm>

namespace cfg {
namespace {

// Without a size hint the first block holds a small file's model; each next one is twice the
// last, up to 4 MiB, so owns() stays a short scan of a few blocks.
constexpr std::size_t kFirstBlock = std::size_t{64} << 10;
constexpr std::size_t kLargestBlock = std::size_t{4} << 20;
constexpr std::size_t kTextsPerChunk = 1024;

#if defined(__linux__) && defined(MADV_HUGEPAGE)
// A large block (a reader's first block is 1.5x the file) is marked for transparent huge pages
// in its 2 MiB-aligned interior: building the model of a 3 MB file then takes a few page faults
// instead of a thousand, which were a tenth of a tool's run (issue 9, perf). A hint only: where
// the kernel gives no huge pages the block is faulted page by page as before.
void advise_huge_pages(std::byte* block, std::size_t size) {
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(block);
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t last = (begin + size) & ~(kHugePage - 1);
  if (first < last) {
    // NOLINTNEXTLINE(performance-no-int-to-ptr): an address inside the block
    madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
  }
}
#else
void advise_huge_pages(std::byte*, std::size_t) {}
#endif

}  // namespace

ModelArena::~ModelArena() = default;

void* ModelArena::allocate(std::size_t bytes, std::size_t align) {
  if (sealed_ || align > alignof(std::max_align_t)) throw std::bad_alloc();
  // Addresses as integers: an aligned position past the block is never formed as a pointer.
  auto fits = [&](std::uintptr_t& at) {
    if (next_ == nullptr) return false;
    at = (reinterpret_cast<std::uintptr_t>(next_) + align - 1) & ~(std::uintptr_t{align} - 1);
    const auto end = reinterpret_cast<std::uintptr_t>(end_);
    return at <= end && end - at >= bytes;
  };
  std::uintptr_t at = 0;
  if (!fits(at)) {
    std::size_t size = 0;
    if (blocks_.empty()) {
      size = first_block_ != 0 ? first_block_ : kFirstBlock;
      next_block_ = kFirstBlock;
    } else {
      size = next_block_;
      next_block_ = std::min(next_block_ * 2, kLargestBlock);
    }
    size = std::max(size, bytes);  // operator new[] aligns to max_align_t
    blocks_.push_back({std::make_unique_for_overwrite<std::byte[]>(size), size});
    next_ = blocks_.back().bytes.get();
    end_ = next_ + size;
    advise_huge_pages(next_, size);
    at = reinterpret_cast<std::uintptr_t>(next_);
  }
  auto* p = next_ + (at - reinterpret_cast<std::uintptr_t>(next_));
  next_ = p + bytes;
  return p;
}

bool ModelArena::owns(const void* p) const {
  const auto v = reinterpret_cast<std::uintptr_t>(p);
  return std::any_of(blocks_.begin(), blocks_.end(), [v](const Block& b) {
    const auto begin = reinterpret_cast<std::uintptr_t>(b.bytes.get());
    return v >= begin && v - begin < b.size;
  });
}

std::string* ModelArena::new_text(std::string_view text) {
  if (texts_.empty() || texts_used_ == kTextsPerChunk) {
    texts_.push_back(std::make_unique<std::string[]>(kTextsPerChunk));
    texts_used_ = 0;
  }
  std::string* s = &texts_.back()[texts_used_++];
  s->assign(text);
  return s;
}

std::size_t ModelArena::capacity() const {
  std::size_t n = 0;
  for (const Block& b : blocks_) n += b.size;
  return n + texts_.size() * kTextsPerChunk * sizeof(std::string);
}

}  // namespace cfg
