/* Stands in for libglfw on a headless GPU machine: the window backend links
   it, the EGL backend never calls it. glfwInit fails, so --backend window
   there reports that no window system is available. */
#include <stddef.h>

int glfwInit(void) { return 0; }
void glfwTerminate(void) {}
int glfwGetError(const char** description) {
  if (description) *description = "no window system on this machine (the packed GLFW is a stand-in)";
  return 0x00010001;
}
void glfwWindowHint(int hint, int value) {
  (void)hint;
  (void)value;
}
void* glfwCreateWindow(int width, int height, const char* title, void* monitor, void* share) {
  (void)width;
  (void)height;
  (void)title;
  (void)monitor;
  (void)share;
  return NULL;
}
void glfwDestroyWindow(void* window) { (void)window; }
void glfwMakeContextCurrent(void* window) { (void)window; }
void glfwSwapInterval(int interval) { (void)interval; }
void* glfwGetProcAddress(const char* name) {
  (void)name;
  return NULL;
}
void glfwSwapBuffers(void* window) { (void)window; }
void glfwPollEvents(void) {}
int glfwWindowShouldClose(void* window) {
  (void)window;
  return 1;
}
