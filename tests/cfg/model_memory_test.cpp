// The model's memory (cfg/model_memory.hpp): a model read from a file keeps its map nodes and
// value texts in an arena, and no part of it that leaves the model (a moved text, a moved map,
// a copy) depends on the model still being there. Run under ASan (-DCANOPEN_SANITIZE=ON) these
// tests are what catches a dangling arena pointer.
#include "cfg/model_memory.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <utility>

#include "cfg/device_file.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {
namespace {

// A RECORD with two sub-objects and a VAR, the values long enough that std::string keeps them
// outside the object (no short-string buffer hides a dangling pointer).
constexpr std::string_view kText =
    "[DeviceInfo]\nVendorName=Test\n"
    "[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=2\n"
    "[1018sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\nDataType=0x0005\n"
    "AccessType=ro\nDefaultValue=1\nPDOMapping=0\n"
    "[1018sub1]\nParameterName=Vendor-ID\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
    "DefaultValue=0x00000001\nParameterValue=0x00000000000000000000000000000001\nPDOMapping=0\n"
    "[2000]\nParameterName=Device name\nObjectType=0x7\nDataType=0x0009\nAccessType=rw\n"
    "DefaultValue=a visible string longer than sixteen characters\nPDOMapping=0\n";

DeviceDescription read_model() {
  auto r = parse_device_description(kText);
  EXPECT_TRUE(r.device) << r.diagnostics.format();
  return r.device ? std::move(*r.device) : DeviceDescription{};
}

TEST(ModelMemory, AModelReadFromAFileLivesInASealedArena) {
  const DeviceDescription d = read_model();
  const auto arena = d.objects.get_allocator().arena();
  ASSERT_NE(arena, nullptr);
  EXPECT_TRUE(arena->sealed());
  const Object* record = d.object(0x1018);
  ASSERT_NE(record, nullptr);
  EXPECT_EQ(record->subs.get_allocator().arena(), arena);  // sub-objects too, not only objects
  EXPECT_TRUE(arena->owns(record));
  EXPECT_TRUE(arena->owns(record->sub(1)));
}

TEST(ModelMemory, ATextMovedOutOfTheModelOutlivesIt) {
  OptionalText kept;
  OptionalText assigned = "old";
  {
    DeviceDescription d = read_model();
    kept = std::move(d.sub(0x2000, 0)->default_value);
    OptionalText constructed(std::move(d.sub(0x1018, 1)->parameter_value));
    assigned = constructed;
  }
  EXPECT_EQ(kept, "a visible string longer than sixteen characters");
  EXPECT_EQ(assigned, "0x00000000000000000000000000000001");
}

TEST(ModelMemory, ASubObjectMovedOutOfTheModelOutlivesIt) {
  SubObject s;
  {
    DeviceDescription d = read_model();
    s = std::move(*d.sub(0x1018, 1));
  }
  EXPECT_EQ(s.name, "Vendor-ID");
  EXPECT_EQ(s.default_value, "0x00000001");
  EXPECT_EQ(s.parameter_value, "0x00000000000000000000000000000001");
}

TEST(ModelMemory, AMapMovedOutOfTheModelKeepsTheArenaAlive) {
  SubObjects subs;
  {
    DeviceDescription d = read_model();
    subs = std::move(d.object(0x1018)->subs);
  }
  ASSERT_EQ(subs.size(), 2u);
  EXPECT_EQ(subs.at(1).parameter_value, "0x00000000000000000000000000000001");
  subs[7].name = "added after the model is gone";  // the sealed arena sends it to the heap
  EXPECT_EQ(subs.size(), 3u);
}

TEST(ModelMemory, ACopyIsOnTheHeapAndIndependent) {
  std::optional<DeviceDescription> copy;
  {
    const DeviceDescription d = read_model();
    copy = d;
    EXPECT_EQ(*copy, d);
  }
  EXPECT_EQ(copy->objects.get_allocator().arena(), nullptr);
  EXPECT_EQ(copy->sub(0x2000, 0)->default_value, "a visible string longer than sixteen characters");
}

TEST(ModelMemory, EditsAfterTheReadAllocateFromTheHeap) {
  DeviceDescription d = read_model();
  const auto arena = d.objects.get_allocator().arena();
  ASSERT_NE(arena, nullptr);
  const std::size_t before = arena->capacity();
  Object& added = d.objects[0x2001];
  added.subs[0].default_value = "a value set by a tool after reading the file";
  d.sub(0x1018, 1)->parameter_value = "0x00000002";  // in place, where the text already is
  d.objects.erase(0x1018);                           // arena nodes are not freed one by one
  EXPECT_EQ(arena->capacity(), before);
  EXPECT_FALSE(arena->owns(&added));
  EXPECT_EQ(d.sub(0x2001, 0)->default_value, "a value set by a tool after reading the file");
}

TEST(ModelMemory, ArenaAlignsAndRefusesAllocationOnceSealed) {
  ModelArena arena;
  void* a = arena.allocate(3, 1);
  void* b = arena.allocate(sizeof(std::uint64_t), alignof(std::uint64_t));
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(b) % alignof(std::uint64_t), 0u);
  EXPECT_TRUE(arena.owns(a));
  EXPECT_TRUE(arena.owns(b));
  void* big = arena.allocate(std::size_t{8} << 20, 16);  // larger than any block size
  EXPECT_TRUE(arena.owns(big));
  int outside = 0;
  EXPECT_FALSE(arena.owns(&outside));
  arena.seal();
  EXPECT_THROW((void)arena.allocate(1, 1), std::bad_alloc);
}

}  // namespace
}  // namespace cfg

// A block of 2 MiB or more gets huge pages advised on its aligned interior (madvise): every
// byte of it stays usable, and owns() ends where the block ends, also for a size that is not a
// multiple of the page size.
TEST(ModelMemory, LargeBlockIsUsableToItsLastByte) {
  const std::size_t size = (std::size_t{3} << 20) + 123;
  cfg::ModelArena arena(size);
  auto* first = static_cast<unsigned char*>(arena.allocate(size, 1));
  std::memset(first, 0xA5, size);  // faults in every page: a short mapping would crash here
  EXPECT_EQ(first[0], 0xA5);
  EXPECT_EQ(first[size - 1], 0xA5);
  EXPECT_TRUE(arena.owns(first));
  EXPECT_TRUE(arena.owns(first + size - 1));
  EXPECT_GE(arena.capacity(), size);
  // The next allocation never overlaps the bytes handed out.
  auto* next = static_cast<unsigned char*>(arena.allocate(16, 1));
  EXPECT_TRUE(arena.owns(next));
  EXPECT_TRUE(next < first || next >= first + size);
}
