#pragma once
// The OpenGL 4.5 core entry points the client uses, loaded through the
// backend's get-proc-address so that one renderer runs on OSMesa, EGL and
// GLFW contexts alike (no link-time libGL).

#include "phasecast/client/render_backend.h"

#include <GL/glcorearb.h>

namespace phasecast::client::detail {

#define PHASECAST_GL_FUNCTIONS(X)                                        \
  X(PFNGLGETSTRINGPROC, glGetString)                                     \
  X(PFNGLGETERRORPROC, glGetError)                                       \
  X(PFNGLGETINTEGERVPROC, glGetIntegerv)                                 \
  X(PFNGLVIEWPORTPROC, glViewport)                                       \
  X(PFNGLCLEARCOLORPROC, glClearColor)                                   \
  X(PFNGLCLEARPROC, glClear)                                             \
  X(PFNGLENABLEPROC, glEnable)                                           \
  X(PFNGLDISABLEPROC, glDisable)                                         \
  X(PFNGLDEPTHFUNCPROC, glDepthFunc)                                     \
  X(PFNGLFINISHPROC, glFinish)                                           \
  X(PFNGLPIXELSTOREIPROC, glPixelStorei)                                 \
  X(PFNGLREADPIXELSPROC, glReadPixels)                                   \
  X(PFNGLCREATESHADERPROC, glCreateShader)                               \
  X(PFNGLSHADERSOURCEPROC, glShaderSource)                               \
  X(PFNGLCOMPILESHADERPROC, glCompileShader)                             \
  X(PFNGLGETSHADERIVPROC, glGetShaderiv)                                 \
  X(PFNGLGETSHADERINFOLOGPROC, glGetShaderInfoLog)                       \
  X(PFNGLDELETESHADERPROC, glDeleteShader)                               \
  X(PFNGLCREATEPROGRAMPROC, glCreateProgram)                             \
  X(PFNGLATTACHSHADERPROC, glAttachShader)                               \
  X(PFNGLLINKPROGRAMPROC, glLinkProgram)                                 \
  X(PFNGLGETPROGRAMIVPROC, glGetProgramiv)                               \
  X(PFNGLGETPROGRAMINFOLOGPROC, glGetProgramInfoLog)                     \
  X(PFNGLDELETEPROGRAMPROC, glDeleteProgram)                             \
  X(PFNGLUSEPROGRAMPROC, glUseProgram)                                   \
  X(PFNGLTRANSFORMFEEDBACKVARYINGSPROC, glTransformFeedbackVaryings)     \
  X(PFNGLGETUNIFORMLOCATIONPROC, glGetUniformLocation)                   \
  X(PFNGLUNIFORM1IPROC, glUniform1i)                                     \
  X(PFNGLUNIFORM1FPROC, glUniform1f)                                     \
  X(PFNGLUNIFORM2FPROC, glUniform2f)                                     \
  X(PFNGLUNIFORM3FPROC, glUniform3f)                                     \
  X(PFNGLUNIFORM4FVPROC, glUniform4fv)                                   \
  X(PFNGLUNIFORMMATRIX4FVPROC, glUniformMatrix4fv)                       \
  X(PFNGLGENBUFFERSPROC, glGenBuffers)                                   \
  X(PFNGLDELETEBUFFERSPROC, glDeleteBuffers)                             \
  X(PFNGLBINDBUFFERPROC, glBindBuffer)                                   \
  X(PFNGLBINDBUFFERBASEPROC, glBindBufferBase)                           \
  X(PFNGLBINDBUFFERRANGEPROC, glBindBufferRange)                         \
  X(PFNGLBUFFERDATAPROC, glBufferData)                                   \
  X(PFNGLBUFFERSUBDATAPROC, glBufferSubData)                             \
  X(PFNGLGETBUFFERSUBDATAPROC, glGetBufferSubData)                       \
  X(PFNGLGENVERTEXARRAYSPROC, glGenVertexArrays)                         \
  X(PFNGLDELETEVERTEXARRAYSPROC, glDeleteVertexArrays)                   \
  X(PFNGLBINDVERTEXARRAYPROC, glBindVertexArray)                         \
  X(PFNGLVERTEXATTRIBPOINTERPROC, glVertexAttribPointer)                 \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, glEnableVertexAttribArray)         \
  X(PFNGLGENFRAMEBUFFERSPROC, glGenFramebuffers)                         \
  X(PFNGLDELETEFRAMEBUFFERSPROC, glDeleteFramebuffers)                   \
  X(PFNGLBINDFRAMEBUFFERPROC, glBindFramebuffer)                         \
  X(PFNGLGENRENDERBUFFERSPROC, glGenRenderbuffers)                       \
  X(PFNGLDELETERENDERBUFFERSPROC, glDeleteRenderbuffers)                 \
  X(PFNGLBINDRENDERBUFFERPROC, glBindRenderbuffer)                       \
  X(PFNGLRENDERBUFFERSTORAGEPROC, glRenderbufferStorage)                 \
  X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, glFramebufferRenderbuffer)         \
  X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, glCheckFramebufferStatus)           \
  X(PFNGLBLITFRAMEBUFFERPROC, glBlitFramebuffer)                         \
  X(PFNGLREADBUFFERPROC, glReadBuffer)                                   \
  X(PFNGLDRAWELEMENTSPROC, glDrawElements)                               \
  X(PFNGLDRAWARRAYSPROC, glDrawArrays)                                   \
  X(PFNGLDRAWARRAYSINSTANCEDPROC, glDrawArraysInstanced)                 \
  X(PFNGLDRAWELEMENTSINSTANCEDPROC, glDrawElementsInstanced)             \
  X(PFNGLMULTIDRAWELEMENTSBASEVERTEXPROC, glMultiDrawElementsBaseVertex) \
  X(PFNGLBEGINTRANSFORMFEEDBACKPROC, glBeginTransformFeedback)           \
  X(PFNGLENDTRANSFORMFEEDBACKPROC, glEndTransformFeedback)               \
  X(PFNGLMEMORYBARRIERPROC, glMemoryBarrier)                             \
  X(PFNGLDISPATCHCOMPUTEPROC, glDispatchCompute)                         \
  X(PFNGLGENTEXTURESPROC, glGenTextures)                                 \
  X(PFNGLDELETETEXTURESPROC, glDeleteTextures)                           \
  X(PFNGLACTIVETEXTUREPROC, glActiveTexture)                             \
  X(PFNGLBINDTEXTUREPROC, glBindTexture)                                 \
  X(PFNGLTEXBUFFERPROC, glTexBuffer)

// One pointer per entry point, named as in GL.
struct GlFunctions {
#define PHASECAST_GL_MEMBER(type, name) type name = nullptr;
  PHASECAST_GL_FUNCTIONS(PHASECAST_GL_MEMBER)
#undef PHASECAST_GL_MEMBER
};

// Loads every entry point from the backend's current context; throws
// RenderError naming the first one missing.
GlFunctions load_gl_functions(RenderBackend& backend);

}  // namespace phasecast::client::detail
