// The memory a model read from a file lives in: a few large blocks instead of a heap allocation
// per map node and per value text, so that building a model and dropping it cost a few
// allocations, not tens of thousands (they were much of a tool's whole run on a 3 MB DCF).
//
// Who uses it: the EDS/DCF reader builds DeviceDescription's maps with ModelAllocator and keeps
// value texts (OptionalText) in the arena; after the read the arena is sealed and serves no more
// allocations, so a model edited afterwards, from any thread, allocates from the heap as before.
// Nothing else needs to know: the maps' allocators keep the arena alive (shared ownership) for
// as long as a map that came from it exists, copies of a model or of its maps are plain heap
// copies, and an OptionalText moved out of a model takes its text to the heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace cfg {

/// Blocks of memory handed out by bumping a pointer, never freed one by one, plus a pool of
/// std::string objects (the texts of OptionalText). Everything goes when the arena goes.
/// Not thread-safe while it allocates (a reader uses it from one thread); owns() is safe to call
/// from any thread once the arena is sealed.
class ModelArena {
 public:
  ModelArena() = default;
  /// The first block holds `first_block_bytes` (a reader passes what it expects the model to
  /// take, from the file size); later blocks start small and double.
  explicit ModelArena(std::size_t first_block_bytes) : first_block_(first_block_bytes) {}
  ModelArena(const ModelArena&) = delete;
  ModelArena& operator=(const ModelArena&) = delete;
  ~ModelArena();

  /// `bytes` aligned to `align` (at most alignof(std::max_align_t)); throws std::bad_alloc.
  void* allocate(std::size_t bytes, std::size_t align);
  /// Whether `p` points into one of the arena's blocks (then it must not be freed).
  bool owns(const void* p) const;
  /// A string in the pool, holding `text`; destroyed with the arena.
  std::string* new_text(std::string_view text);
  /// No more allocations from here on: allocate() is refused (ModelAllocator then uses the
  /// heap). Memory already handed out stays valid until the arena is destroyed.
  void seal() { sealed_ = true; }
  bool sealed() const { return sealed_; }
  /// Bytes in blocks, for benchmarks and tests.
  std::size_t capacity() const;

 private:
  struct Block {
    std::byte* bytes = nullptr;  // owned: operator new[], or mmap when `mapped`
    std::size_t size = 0;
    bool mapped = false;
  };
  std::size_t first_block_ = 0;  // 0: the default size
  std::size_t next_block_ = 0;   // size of the next block after the first
  std::vector<Block> blocks_;
  std::byte* next_ = nullptr;
  std::byte* end_ = nullptr;
  std::vector<std::unique_ptr<std::string[]>> texts_;
  std::size_t texts_used_ = 0;  // in texts_.back()
  bool sealed_ = false;
};

/// An allocator for the model's maps: from the arena while it is open, else from the heap.
/// Memory from the arena is never freed one piece at a time (deallocate() ignores it); the
/// allocator holds a share of the arena, so nodes stay valid as long as their map exists.
/// A default-constructed allocator is the heap (std::allocator), and so is the allocator of a
/// copied map (select_on_container_copy_construction).
template <class T>
class ModelAllocator {
 public:
  using value_type = T;
  using propagate_on_container_move_assignment = std::true_type;
  using propagate_on_container_swap = std::true_type;
  using propagate_on_container_copy_assignment = std::false_type;
  using is_always_equal = std::false_type;

  ModelAllocator() noexcept = default;
  // Copied, never moved from: a map keeps its share of the arena when its nodes are moved to
  // another map (a moved-from allocator would send the map's next nodes to the heap).
  ModelAllocator(const ModelAllocator&) noexcept = default;
  ModelAllocator& operator=(const ModelAllocator&) noexcept = default;
  ~ModelAllocator() = default;
  explicit ModelAllocator(std::shared_ptr<ModelArena> arena) noexcept : arena_(std::move(arena)) {}
  template <class U>
  ModelAllocator(const ModelAllocator<U>& other) noexcept  // NOLINT(google-explicit-constructor)
      : arena_(other.arena()) {}

  T* allocate(std::size_t n) {
    if (arena_ && !arena_->sealed()) {
      return static_cast<T*>(arena_->allocate(n * sizeof(T), alignof(T)));
    }
    return std::allocator<T>().allocate(n);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (arena_ && arena_->owns(p)) return;  // freed with the arena
    std::allocator<T>().deallocate(p, n);
  }
  ModelAllocator select_on_container_copy_construction() const { return {}; }

  /// By value: containers hand out their allocator by value (get_allocator()), so a reference
  /// would dangle at the end of the statement.
  std::shared_ptr<ModelArena> arena() const { return arena_; }

  template <class U>
  friend bool operator==(const ModelAllocator& a, const ModelAllocator<U>& b) {
    return a.arena_ == b.arena();
  }

 private:
  std::shared_ptr<ModelArena> arena_;
};

}  // namespace cfg
