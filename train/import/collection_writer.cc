#include "train/import/collection_writer.h"

#include <set>

#include "common/error.h"
#include "common/io/gravity_file.h"
#include "common/io/session_file.h"

namespace lmb {

namespace fs = std::filesystem;

void write_collection(const fs::path& out_dir, const std::map<int, Camera>& cameras,
                      const std::vector<CollectionImage>& images, bool overwrite,
                      const std::vector<MapSession>& sessions) {
  LMB_CHECK(!images.empty(), out_dir.string() << ": no image to write into the collection");
  size_t with_gravity = 0;
  std::set<std::string> names;
  for (const CollectionImage& im : images) {
    LMB_CHECK(names.insert(im.image.name).second, out_dir.string()
                                                      << ": image name " << im.image.name << " used twice");
    check_image_name(im.image.name, out_dir.string());
    LMB_CHECK(im.image.name.find_first_of(" \t\n") == std::string::npos,
              im.image.name << ": image names must not contain white space (COLMAP text format)");
    LMB_CHECK(fs::is_regular_file(im.source), im.source.string() << ": source image is missing");
    LMB_CHECK(cameras.count(im.image.camera_id), im.image.name << ": unknown camera " << im.image.camera_id);
    with_gravity += im.gravity_in_cam.has_value();
  }
  if (!sessions.empty()) {
    ColmapModel named;
    for (const CollectionImage& im : images) named.images.push_back(im.image);
    image_sessions(sessions, named, out_dir / kSessionFileName);
  }
  LMB_CHECK(with_gravity == 0 || with_gravity == images.size(),
            out_dir.string() << ": gravity known for " << with_gravity << " of " << images.size()
                             << " images; it must be known for all or none");

  if (fs::exists(out_dir) && !fs::is_empty(out_dir)) {
    LMB_CHECK(overwrite, out_dir.string() << ": output folder exists and is not empty (use --overwrite to replace "
                                             "its sparse/, images/, gravity.txt and sessions.txt)");
    fs::remove_all(out_dir / "sparse");
    fs::remove_all(out_dir / "images");
    fs::remove(out_dir / "gravity.txt");
    fs::remove(out_dir / kSessionFileName);
  }
  // A failed write (a full disk) leaves no half collection: what this call created is removed, OUT
  // and the folders above it included when this call created them (innermost first; each only
  // when empty).
  std::vector<fs::path> created_folders;
  for (fs::path p = fs::absolute(out_dir).lexically_normal(); p != p.parent_path(); p = p.parent_path()) {
    if (p.filename().empty()) continue;  // a trailing separator
    std::error_code ec;
    if (fs::exists(p, ec) || ec) break;
    created_folders.push_back(p);
  }
  auto remove_outputs = [&] {
    std::error_code ec;
    fs::remove_all(out_dir / "sparse", ec);
    fs::remove_all(out_dir / "images", ec);
    fs::remove(out_dir / "gravity.txt", ec);
    fs::remove(out_dir / kSessionFileName, ec);
    for (const fs::path& p : created_folders) fs::remove(p, ec);
  };
  try {
    std::error_code ec;
    fs::create_directories(out_dir / "images", ec);
    LMB_CHECK(!ec, (out_dir / "images").string() << ": cannot create the folder: " << ec.message());
    ColmapModel model;
    model.cameras = cameras;
    std::map<std::string, Eigen::Vector3d> gravity;
    for (const CollectionImage& im : images) {
      const fs::path link = out_dir / "images" / im.image.name;
      fs::create_directories(link.parent_path(), ec);
      LMB_CHECK(!ec, link.parent_path().string() << ": cannot create the folder: " << ec.message());
      fs::create_symlink(fs::absolute(im.source).lexically_normal(), link, ec);
      LMB_CHECK(!ec, link.string() << ": cannot create symbolic link: " << ec.message());
      model.images.push_back(im.image);
      if (im.gravity_in_cam) gravity[im.image.name] = *im.gravity_in_cam;
    }
    write_colmap_text(model, out_dir / "sparse");
    if (!gravity.empty()) write_gravity_file(gravity, out_dir / "gravity.txt");
    if (!sessions.empty()) write_session_file(sessions, out_dir / kSessionFileName);
  } catch (...) {
    remove_outputs();
    throw;
  }
}

}  // namespace lmb
