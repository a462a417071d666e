// The Assimp reader: every mesh format Assimp reads, through its 32-bit floats (see the
// precision note in qota/mesh_io.hpp).

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <Eigen/Core>
#include <assimp/Importer.hpp>
#include <functional>
#include <string>
#include <vector>

#include "mesh_readers.hpp"
#include "qota/error.hpp"

namespace qota::detail {
namespace {

// Single-precision Assimp is what the header's precision note is about; if a double build shows
// up, the note (and MeshFile::singlePrecision) must say so, and OBJ could go through it too.
constexpr bool kAssimpSinglePrecision = sizeof(ai_real) == sizeof(float);

std::string assimpError(const std::string& path, const Assimp::Importer& importer) {
  const char* m = importer.GetErrorString();
  return path + ": Assimp cannot read it" + ((m && *m) ? std::string(": ") + m : std::string());
}

}  // namespace

void readAssimp(MeshFile& out, const MeshFileOptions& options, const std::string& ext) {
  Assimp::Importer importer;
  // No triangulation (Mesh takes convex polygons, and Builder cuts the others), no other
  // clean-up: Builder joins vertices by exact position across meshes, which JoinIdenticalVertices
  // (per mesh, and only when normals and texture coordinates agree too) cannot do alone.
  const aiScene* scene = importer.ReadFile(out.path, aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure);
  if (!scene) throw Error(assimpError(out.path, importer));
  if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE || !scene->mRootNode) {
    throw Error(out.path + ": Assimp read an incomplete scene (no geometry)");
  }
  out.format = "assimp:" + ext;
  out.singlePrecision = kAssimpSinglePrecision;
  Builder builder(out, options);

  std::function<void(const aiNode*, const Eigen::Matrix4d&)> walk = [&](const aiNode* node,
                                                                        const Eigen::Matrix4d& parent) {
    const aiMatrix4x4& t = node->mTransformation;
    Eigen::Matrix4d local;
    local << t.a1, t.a2, t.a3, t.a4, t.b1, t.b2, t.b3, t.b4, t.c1, t.c2, t.c3, t.c4, t.d1, t.d2, t.d3, t.d4;
    const Eigen::Matrix4d world = parent * local;
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      const aiMesh* mesh = scene->mMeshes[node->mMeshes[k]];
      std::string materialName;
      if (mesh->mMaterialIndex < scene->mNumMaterials) {
        aiString name;
        if (scene->mMaterials[mesh->mMaterialIndex]->Get(AI_MATKEY_NAME, name) == AI_SUCCESS) {
          materialName = name.C_Str();
        }
      }
      const std::string objectName = node->mName.length ? node->mName.C_Str() : mesh->mName.C_Str();
      const std::uint32_t material = builder.material(materialName);
      const std::uint32_t object = builder.object(objectName);
      std::vector<std::uint32_t> id(mesh->mNumVertices);
      for (unsigned i = 0; i < mesh->mNumVertices; ++i) {
        const aiVector3D& q = mesh->mVertices[i];
        const Eigen::Vector3d p =
            world.topLeftCorner<3, 3>() * Eigen::Vector3d(q.x, q.y, q.z) + world.topRightCorner<3, 1>();
        if (!p.allFinite()) {
          throw Error(out.path + ": mesh '" + mesh->mName.C_Str() + "' vertex " + std::to_string(i) +
                      " has a non-finite coordinate");
        }
        id[i] = builder.vertex(p);
      }
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices < 3) continue;  // points and lines carry no surface
        std::vector<std::uint32_t> ring(face.mNumIndices);
        for (unsigned c = 0; c < face.mNumIndices; ++c) ring[c] = id[face.mIndices[c]];
        builder.addFace({std::move(ring)}, material, object, f,
                        [&] { return out.path + ": mesh '" + mesh->mName.C_Str() + "' face " + std::to_string(f); });
      }
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) walk(node->mChildren[c], world);
  };
  walk(scene->mRootNode, Eigen::Matrix4d::Identity());
  builder.finish();
}

}  // namespace qota::detail
