// libFuzzer target: the label-image readers (NRRD, NIfTI-1, MetaImage, INR; raw and
// compressed). The first byte picks the format (the readers dispatch on the file's extension),
// the rest is the file. Every refusal must be an InputError; nothing may read out of bounds or
// allocate beyond what the header's checked size allows.

#include <unistd.h>

#include <cstdio>
#include <string>

#include "tissue/input_error.hpp"
#include "io/label_image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExt[] = {".nrrd", ".nii", ".nii.gz", ".mha", ".inr", ".inr.gz"};
  const std::string path = "/tmp/stroma_fuzz_label_image_" + std::to_string(::getpid()) + kExt[data[0] % 6];
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
  }
  try {
    const stroma::LabelImage im = stroma::read_label_image(path);
    if (im.labels.size() != size_t(im.voxel_count())) __builtin_trap();
  } catch (const stroma::InputError&) {
  }
  std::remove(path.c_str());
  return 0;
}
