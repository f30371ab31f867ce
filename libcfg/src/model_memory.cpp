#include "cfg/model_memory.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>

namespace cfg {
namespace {

// Without a size hint the first block holds a small file's model; each next one is twice the
// last, up to 4 MiB, so owns() stays a short scan of a few blocks.
constexpr std::size_t kFirstBlock = std::size_t{64} << 10;
constexpr std::size_t kLargestBlock = std::size_t{4} << 20;
constexpr std::size_t kTextsPerChunk = 1024;

constexpr std::size_t kHugePage = std::size_t{2} << 20;

#if defined(__linux__) && defined(MADV_HUGEPAGE)
// A block of at least a huge page (a reader's first block is 1.5x the file) is mapped on its own
// at a 2 MiB boundary and marked for transparent huge pages as a whole: building the model of a
// 3 MB file then takes a few page faults instead of a thousand, which were a tenth of a tool's
// run. On the heap, only a block's aligned interior could be marked. A hint
// only: where the kernel gives no huge pages the block is faulted page by page. nullptr when
// the mapping fails (the caller then takes the heap).
std::byte* map_huge_block(std::size_t size) {
  const std::size_t length = size + kHugePage;  // room to align the start
  void* p = mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return nullptr;
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t aligned = (begin + kHugePage - 1) & ~(std::uintptr_t{kHugePage} - 1);
  // Give back the unaligned head and the tail beyond `size` (from the page that follows it:
  // munmap takes page-aligned addresses only).
  // NOLINTBEGIN(performance-no-int-to-ptr): addresses inside the mapping
  if (aligned > begin) munmap(p, aligned - begin);
  const std::uintptr_t end = begin + length;
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const std::uintptr_t used_end = (aligned + size + page - 1) & ~(page - 1);
  if (end > used_end) munmap(reinterpret_cast<void*>(used_end), end - used_end);
  auto* block = reinterpret_cast<std::byte*>(aligned);
  // NOLINTEND(performance-no-int-to-ptr)
  madvise(block, size, MADV_HUGEPAGE);
  return block;
}
void unmap_block(std::byte* block, std::size_t size) {
  munmap(block, size);
}
#else
std::byte* map_huge_block(std::size_t) {
  return nullptr;
}
void unmap_block(std::byte*, std::size_t) {}
#endif

}  // namespace

ModelArena::~ModelArena() {
  for (const Block& b : blocks_) {
    if (b.mapped) {
      unmap_block(b.bytes, b.size);
    } else {
      delete[] b.bytes;
    }
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
    size = std::max(size, bytes);
    blocks_.reserve(blocks_.size() + 1);  // no leak if this throws
    Block block{nullptr, size, false};
    if (size >= kHugePage) {
      block.bytes = map_huge_block(size);
      block.mapped = block.bytes != nullptr;
    }
    if (block.bytes == nullptr) block.bytes = new std::byte[size];  // aligned to max_align_t
    blocks_.push_back(block);
    next_ = block.bytes;
    end_ = next_ + size;
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
