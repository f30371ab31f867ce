// SlaveNode's program memory (DSP 302 §9, program download): the images written to 1F50h sub N,
// kept over resets and power cycles, and the version 1F52h reports for program number 1. Where
// the device file has them, CiA 302-3's 1F56h sub N (program software identification: the
// CRC-32 of the image, our simulated devices' choice) and 1F57h sub N (flash status
// identification: 0 after a download, "no valid program" after a clear). The
// image format is the manufacturer's (§9); a simulated device learns an image's version from our
// trailer convention (cfg/program_image.hpp), the rest of the image is opaque to it.
#include <string>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/object_index.hpp"
#include "cfg/program_image.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

namespace obj = cfg::object;

void SlaveNode::report_program_version(const cfg::ProgramVersion& version) {
  // The object is optional (a file without 1F52h gets none, see the top of slave_node.hpp).
  if (dict_.entry(obj::kVerifyApplicationSoftware, 1)) {
    dict_.set_unsigned(obj::kVerifyApplicationSoftware, 1, version.date_days);
  }
  if (dict_.entry(obj::kVerifyApplicationSoftware, 2)) {
    dict_.set_unsigned(obj::kVerifyApplicationSoftware, 2, version.time_ms);
  }
}

void SlaveNode::program_downloaded(std::uint8_t program, std::span<const std::uint8_t> image,
                                   TimePoint now, Output& out) {
  program_images_[program].assign(image.begin(), image.end());
  set_program_state(program, ProgramState::Stopped);
  if (dict_.entry(obj::kProgramSoftwareIdentification, program)) {
    dict_.set_unsigned(obj::kProgramSoftwareIdentification, program, cfg::crc32(image));
  }
  set_flash_status(program, kFlashStatusOk);
  const auto version = cfg::program_image_version(image);
  // DSP 302 §9: 1F52h verifies "the stored program number 1". An image with a trailer reports
  // its version once started (program_state_changed); one without it gets the options' version
  // now (unset: the node does not know it, 1F52h stays).
  if (program == 1 && !version && options_.downloaded_program_version) {
    report_program_version(*options_.downloaded_program_version);
  }
  emit(out, SlaveEvent::Kind::Program, now,
       "program " + std::to_string(program) + " downloaded, " + std::to_string(image.size()) +
           " bytes" + (version ? ", version " + cfg::to_string(*version) : std::string()));
}

void SlaveNode::program_state_changed(std::uint8_t program, ProgramState state) {
  if (state == ProgramState::NoProgram) {
    program_images_.erase(program);  // clear (1F51h = 3, CiA 302-3)
    set_flash_status(program, kFlashStatusNoProgram);
    return;
  }
  if (program != 1 || state != ProgramState::Running) return;
  const auto image = program_images_.find(program);
  if (image == program_images_.end()) return;  // the program the device file came with
  if (const auto version = cfg::program_image_version(image->second)) {
    report_program_version(*version);
  } else if (options_.downloaded_program_version) {
    // An image without a trailer, e.g. restored from an earlier run: the version its download
    // was given.
    report_program_version(*options_.downloaded_program_version);
  }
}

void SlaveNode::set_flash_status(std::uint8_t program, std::uint32_t value) {
  if (dict_.entry(obj::kFlashStatusIdentification, program)) {
    dict_.set_unsigned(obj::kFlashStatusIdentification, program, value);
  }
}

void SlaveNode::set_program_images(std::map<std::uint8_t, std::vector<std::uint8_t>> images) {
  program_images_.clear();
  for (auto& [program, image] : images) {
    if (program == 0 || !dict_.entry(obj::kProgramData, program)) continue;
    dict_.set_bytes(obj::kProgramData, program, image);
    if (dict_.entry(obj::kProgramSoftwareIdentification, program)) {
      dict_.set_unsigned(obj::kProgramSoftwareIdentification, program, cfg::crc32(image));
    }
    program_images_[program] = std::move(image);
    // A program that was cleared in the file's default is there now; start() starts it.
    const auto state = programs_.find(program);
    if (state != programs_.end() && state->second == ProgramState::NoProgram) {
      programs_[program] = ProgramState::Stopped;
      dict_.set_unsigned(obj::kProgramControl, program,
                         static_cast<std::uint8_t>(ProgramState::Stopped));
    }
  }
}

}  // namespace nmt
