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

}  // namespace

#if defined(__linux__) && defined(MADV_HUGEPAGE)
// Large blocks (a reader's first block is 1.5x the file) are mapped 2 MiB-aligned and marked
// for transparent huge pages: building the model of a 3 MB file then takes a few page faults
// instead of a thousand, which were a tenth of a tool's run (issue 9, perf). Where the kernel
// gives no huge pages the block is an ordinary mapping, faulted page by page as before.
constexpr std::size_t kHugePage = std::size_t{2} << 20;

ModelArena::Block ModelArena::new_block(std::size_t size) {
  if (size >= kHugePage) {
    // Not rounded up: the 2 MiB pages inside the block are huge, its tail has small pages, so a
    // model touches at most one huge page it does not fill.
    const std::size_t rounded = (size + 4095) & ~std::size_t{4095};
    void* p = mmap(nullptr, rounded + kHugePage, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p != MAP_FAILED) {
      // Keep the 2 MiB-aligned part only (huge pages need aligned addresses).
      const auto begin = reinterpret_cast<std::uintptr_t>(p);
      const std::uintptr_t aligned = (begin + kHugePage - 1) & ~(std::uintptr_t{kHugePage} - 1);
      const std::size_t head = aligned - begin;
      if (head > 0) munmap(p, head);
      // NOLINTNEXTLINE(performance-no-int-to-ptr): the tail of the mapping just made
      munmap(reinterpret_cast<void*>(aligned + rounded), kHugePage - head);
      auto* bytes = reinterpret_cast<std::byte*>(aligned);  // NOLINT(performance-no-int-to-ptr)
      madvise(bytes, rounded, MADV_HUGEPAGE);               // a hint: failure changes nothing
      return {bytes, rounded, true};
    }
  }
  return {new std::byte[size], size, false};
}
#else
ModelArena::Block ModelArena::new_block(std::size_t size) {
  return {new std::byte[size], size, false};
}
#endif

ModelArena::~ModelArena() {
  for (const Block& b : blocks_) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (b.mapped) {
      munmap(b.bytes, b.size);
      continue;
    }
#endif
    delete[] b.bytes;
  }
}

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
    size = std::max(size, bytes);         // operator new[] aligns to max_align_t
    blocks_.reserve(blocks_.size() + 1);  // no throw after the block is allocated
    blocks_.push_back(new_block(size));
    next_ = blocks_.back().bytes;
    end_ = next_ + blocks_.back().size;
    at = reinterpret_cast<std::uintptr_t>(next_);
  }
  auto* p = next_ + (at - reinterpret_cast<std::uintptr_t>(next_));
  next_ = p + bytes;
  return p;
}

bool ModelArena::owns(const void* p) const {
  const auto v = reinterpret_cast<std::uintptr_t>(p);
  return std::any_of(blocks_.begin(), blocks_.end(), [v](const Block& b) {
    const auto begin = reinterpret_cast<std::uintptr_t>(b.bytes);
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
