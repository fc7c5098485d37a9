#pragma once
// Move-only owners of OpenGL object names: each deletes its object when it is
// destroyed, so a renderer that throws half-way through its setup frees what
// it had already made. The GL context the object was made in must still be
// current then (the backend outlives the renderer, render_backend.h).

#include "gl_functions.h"

#include <type_traits>
#include <utility>

namespace phasecast::client::detail {

// Kind says how an object is made and deleted (GeneratedKind, ShaderKind,
// ProgramKind). The delete entry point is copied from the GlFunctions the
// object was made with, so the handle does not point back at them.
template <class Kind>
class GlHandle {
 public:
  using Delete = std::remove_cvref_t<decltype(std::declval<const GlFunctions&>().*Kind::kDelete)>;

  GlHandle() = default;
  // Makes a new object; `args` are what its create call needs (a shader's stage).
  template <class... Args>
  explicit GlHandle(const GlFunctions& gl, Args... args)
      : delete_(gl.*Kind::kDelete), name_(Kind::create(gl, args...)) {}
  ~GlHandle() { reset(); }

  GlHandle(GlHandle&& other) noexcept : delete_(other.delete_), name_(std::exchange(other.name_, 0)) {}
  GlHandle& operator=(GlHandle&& other) noexcept {
    if (this != &other) {
      reset();
      delete_ = other.delete_;
      name_ = std::exchange(other.name_, 0);
    }
    return *this;
  }
  GlHandle(const GlHandle&) = delete;
  GlHandle& operator=(const GlHandle&) = delete;

  // The GL name, 0 for an empty handle (GL's "no object").
  GLuint get() const { return name_; }
  explicit operator bool() const { return name_ != 0; }

 private:
  void reset() {
    if (name_ != 0) Kind::destroy(delete_, name_);
    name_ = 0;
  }

  Delete delete_ = nullptr;
  GLuint name_ = 0;
};

// Objects named by glGen*(n, names) and freed by glDelete*(n, names).
template <auto Gen, auto Del>
struct GeneratedKind {
  static constexpr auto kDelete = Del;
  static GLuint create(const GlFunctions& gl) {
    GLuint name = 0;
    (gl.*Gen)(1, &name);
    return name;
  }
  template <class F>
  static void destroy(F gl_delete, GLuint name) {
    gl_delete(1, &name);
  }
};

struct ShaderKind {
  static constexpr auto kDelete = &GlFunctions::glDeleteShader;
  static GLuint create(const GlFunctions& gl, GLenum stage) { return gl.glCreateShader(stage); }
  static void destroy(PFNGLDELETESHADERPROC gl_delete, GLuint name) { gl_delete(name); }
};

struct ProgramKind {
  static constexpr auto kDelete = &GlFunctions::glDeleteProgram;
  static GLuint create(const GlFunctions& gl) { return gl.glCreateProgram(); }
  static void destroy(PFNGLDELETEPROGRAMPROC gl_delete, GLuint name) { gl_delete(name); }
};

// Distinct types per object kind, though the GL entry points share signatures,
// so a buffer cannot be passed where a vertex array is meant.
using Buffer = GlHandle<GeneratedKind<&GlFunctions::glGenBuffers, &GlFunctions::glDeleteBuffers>>;
using VertexArray =
    GlHandle<GeneratedKind<&GlFunctions::glGenVertexArrays, &GlFunctions::glDeleteVertexArrays>>;
using Framebuffer =
    GlHandle<GeneratedKind<&GlFunctions::glGenFramebuffers, &GlFunctions::glDeleteFramebuffers>>;
using Renderbuffer =
    GlHandle<GeneratedKind<&GlFunctions::glGenRenderbuffers, &GlFunctions::glDeleteRenderbuffers>>;
using Texture = GlHandle<GeneratedKind<&GlFunctions::glGenTextures, &GlFunctions::glDeleteTextures>>;
using Shader = GlHandle<ShaderKind>;
using Program = GlHandle<ProgramKind>;

}  // namespace phasecast::client::detail
