#include "render/gl_context.hpp"

#include <stdexcept>

#include <GL/osmesa.h>
#include <fmt/format.h>

#include "render/gl.hpp"

namespace stroma::render {

struct GlContext::Impl {
  OSMesaContext ctx = nullptr;
  std::vector<uint8_t> buffer;  // OSMesa's own colour buffer (unused for drawing: FBOs are)
};

GlContext::GlContext(int width, int height, int major, int minor) : impl_(std::make_unique<Impl>()) {
  const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 24, OSMESA_STENCIL_BITS, 0,
                         OSMESA_ACCUM_BITS, 0, OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION, major, OSMESA_CONTEXT_MINOR_VERSION, minor, 0};
  impl_->ctx = OSMesaCreateContextAttribs(attribs, nullptr);
  if (!impl_->ctx)
    throw std::runtime_error(fmt::format("OSMesa: cannot create an OpenGL {}.{} core-profile context "
                                         "(is libosmesa6 installed? scripts/setup.sh installs it)", major, minor));
  impl_->buffer.resize(static_cast<size_t>(width) * height * 4);
  if (!OSMesaMakeCurrent(impl_->ctx, impl_->buffer.data(), GL_UNSIGNED_BYTE, width, height)) {
    OSMesaDestroyContext(impl_->ctx);
    throw std::runtime_error(fmt::format("OSMesa: cannot make a {}x{} context current", width, height));
  }
  OSMesaPixelStore(OSMESA_Y_UP, 1);
}

GlContext::~GlContext() {
  if (impl_->ctx) OSMesaDestroyContext(impl_->ctx);
}

std::string GlContext::version() const {
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return s ? s : "";
}

std::string GlContext::renderer() const {
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return s ? s : "";
}

}  // namespace stroma::render
