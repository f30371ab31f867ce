// The generated DCF that the dcf2concise benchmarks read, in-process (bench_dcf2concise) and as
// whole processes (bench_process): one definition so both measure the same bytes.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

namespace bench {

// A DCF for node 5 with `pdos` RPDOs and as many TPDOs (4 communication sub-indices, 8 mapping
// entries each) and `records` manufacturer RECORDs of 16 sub-indices of mixed types, every entry
// with a DefaultValue and a ParameterValue (half of them different).
inline std::string generate_dcf(int pdos, int records) {
  std::string out;
  char buf[256];
  auto line = [&out](const std::string& s) {
    out += s;
    out += "\r\n";
  };
  line("[FileInfo]");
  line("FileName=generated.dcf");
  line("EDSVersion=4.0");
  line("[DeviceInfo]");
  line("VendorName=Bench");
  line("ProductName=Generated");
  line("[DeviceComissioning]");
  line("NodeID=5");
  line("Baudrate=500");
  std::vector<unsigned> indices;
  for (int n = 0; n < pdos; ++n) {
    indices.push_back(0x1400u + static_cast<unsigned>(n));
    indices.push_back(0x1600u + static_cast<unsigned>(n));
    indices.push_back(0x1800u + static_cast<unsigned>(n));
    indices.push_back(0x1A00u + static_cast<unsigned>(n));
  }
  for (int r = 0; r < records; ++r) indices.push_back(0x2000u + static_cast<unsigned>(r));
  std::vector<unsigned> optional;
  std::vector<unsigned> manufacturer;
  for (unsigned i : indices) (i >= 0x2000 ? manufacturer : optional).push_back(i);
  auto list = [&](const char* name, const std::vector<unsigned>& items) {
    line(std::string("[") + name + "]");
    line("SupportedObjects=" + std::to_string(items.size()));
    for (std::size_t k = 0; k < items.size(); ++k) {
      std::snprintf(buf, sizeof buf, "%zu=0x%04X", k + 1, items[k]);
      line(buf);
    }
  };
  list("MandatoryObjects", {0x1000, 0x1001, 0x1018});
  list("OptionalObjects", optional);
  list("ManufacturerObjects", manufacturer);

  auto sub = [&](unsigned index, unsigned s, const char* type, const char* access,
                 const std::string& def, const std::string& value) {
    std::snprintf(buf, sizeof buf, "[%04Xsub%X]", index, s);
    line(buf);
    line("ParameterName=Entry " + std::to_string(s));
    line("ObjectType=0x7");
    line(std::string("DataType=") + type);
    line(std::string("AccessType=") + access);
    line("DefaultValue=" + def);
    line("ParameterValue=" + value);
    line("PDOMapping=0");
  };
  // SubNumber counts the sub-objects written (CiA 306 §4.6.3); sub-index 0 holds the highest.
  auto record = [&](unsigned index, int subs, int highest) {
    std::snprintf(buf, sizeof buf, "[%04X]", index);
    line(buf);
    line("ParameterName=Object");
    line("ObjectType=0x9");
    line("SubNumber=" + std::to_string(subs));
    sub(index, 0, "0x0005", "const", std::to_string(highest), std::to_string(highest));
  };
  // The objects CiA 301 requires of every device, so that the file reads without warnings.
  for (const char* object : {"[1000]\r\nParameterName=Device type\r\nObjectType=0x7\r\n"
                             "DataType=0x0007\r\nAccessType=ro\r\nDefaultValue=0x00000191\r\n"
                             "PDOMapping=0",
                             "[1001]\r\nParameterName=Error register\r\nObjectType=0x7\r\n"
                             "DataType=0x0005\r\nAccessType=ro\r\nDefaultValue=0\r\n"
                             "PDOMapping=1"}) {
    line(object);
  }
  record(0x1018, 2, 1);
  sub(0x1018, 1, "0x0007", "ro", "0x12345678", "0x12345678");
  for (int n = 0; n < pdos; ++n) {
    for (unsigned base : {0x1400u, 0x1800u}) {
      const unsigned comm = base + static_cast<unsigned>(n);
      record(comm, 5, 5);  // sub-indices 0, 1, 2, 3, 5 (4 is reserved)
      std::snprintf(buf, sizeof buf, "$NODEID+0x%X", 0x80000000u + 0x180u + 0x100u * (n % 4));
      sub(comm, 1, "0x0007", "rw", buf, buf);
      sub(comm, 2, "0x0005", "rw", "0xFF", "1");
      sub(comm, 3, "0x0006", "rw", "0", "100");
      sub(comm, 5, "0x0006", "rw", "0", "10");
      const unsigned map = comm + 0x200;
      record(map, 9, 8);
      for (unsigned s = 1; s <= 8; ++s) {
        std::snprintf(buf, sizeof buf, "0x%04X%02X08", 0x2000u + static_cast<unsigned>(n), s);
        sub(map, s, "0x0007", "rw", "0", buf);
      }
    }
  }
  const char* types[] = {"0x0005", "0x0006", "0x0007", "0x0010", "0x0008", "0x0009"};
  const char* values[] = {"0x12", "1000", "0x12345678", "-42", "1.5", "text value"};
  for (int r = 0; r < records; ++r) {
    const unsigned index = 0x2000u + static_cast<unsigned>(r);
    record(index, 17, 16);
    for (unsigned s = 1; s <= 16; ++s) {
      const int t = static_cast<int>(s % 6);
      sub(index, s, types[t], "rw", s % 2 ? values[t] : "0", values[t]);
    }
  }
  return out;
}

/// The input of the dcf2concise figures in BENCHMARKS.md: 2.95 MB, 128 RPDOs + 128 TPDOs and
/// 1000 records, besides 1000h, 1001h and 1018h; it reads without a diagnostic.
inline std::string generated_big_dcf() {
  return generate_dcf(128, 1000);
}

}  // namespace bench
