// The GDAL/OGR reader: the surfaces (polygons, TINs, polyhedral surfaces) of 3D vector datasets,
// in double precision.

#include <gdal_priv.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "gdal_errors.hpp"
#include "mesh_readers.hpp"
#include "qota/error.hpp"

namespace qota::detail {
namespace {

// Layer geometry types that can hold surfaces (the others are skipped when no layer is named).
bool surfaceLayer(OGRwkbGeometryType type) {
  const OGRwkbGeometryType t = wkbFlatten(type);
  return t == wkbUnknown || t == wkbGeometryCollection || OGR_GT_IsSurface(t) ||
         OGR_GT_IsSubClassOf(t, wkbMultiSurface) || OGR_GT_IsSubClassOf(t, wkbPolyhedralSurface);
}

class OgrReader {
 public:
  OgrReader(MeshFile& out, const MeshFileOptions& options) : out_(out), options_(options), builder_(out, options) {}

  void read(GDALDataset& ds) {
    out_.format = std::string("ogr:") + (ds.GetDriver() ? ds.GetDriver()->GetDescription() : "");
    std::vector<OGRLayer*> layers;
    if (!options_.layer.empty()) {
      OGRLayer* layer = ds.GetLayerByName(options_.layer.c_str());
      if (!layer) {
        std::string names;
        for (OGRLayer* l : ds.GetLayers()) names += (names.empty() ? "" : ", ") + std::string(l->GetName());
        throw Error(out_.path + ": no layer '" + options_.layer + "' (layers: " + names + ")");
      }
      layers.push_back(layer);
    } else {
      for (OGRLayer* l : ds.GetLayers()) {
        if (surfaceLayer(l->GetGeomType())) layers.push_back(l);
      }
    }
    const OGRSpatialReference* crs = nullptr;
    for (OGRLayer* layer : layers) {
      if (const OGRSpatialReference* srs = layer->GetSpatialRef()) {
        if (!crs) {
          crs = srs;
          char* wkt = nullptr;
          if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) out_.crsWkt = wkt;
          CPLFree(wkt);
        } else if (!crs->IsSame(srs)) {
          // One mesh has one frame: mixing CRSs would put polygons at meaningless places.
          throw Error(out_.path + ": layer '" + layer->GetName() +
                      "' has a different CRS from the layers before it; name one layer");
        }
      }
      readLayer(*layer);
    }
    builder_.finish();
  }

 private:
  void readLayer(OGRLayer& layer) {
    const std::string name = layer.GetName();
    int field = -1;
    if (!options_.materialField.empty()) {
      field = layer.GetLayerDefn()->GetFieldIndex(options_.materialField.c_str());
      if (field < 0) {
        std::string fields;
        for (int i = 0; i < layer.GetLayerDefn()->GetFieldCount(); ++i) {
          fields += (i ? ", " : "") + std::string(layer.GetLayerDefn()->GetFieldDefn(i)->GetNameRef());
        }
        throw Error(out_.path + ": layer '" + name + "' has no field '" + options_.materialField +
                    "' (fields: " + fields + ")");
      }
    }
    const std::uint32_t layerMaterial = field < 0 ? builder_.material(name) : 0;
    layer.ResetReading();
    std::uint64_t sequence = 0;
    for (auto& feature : layer) {
      const GIntBig fid = feature->GetFID();
      const std::uint64_t id = fid == OGRNullFID ? sequence : static_cast<std::uint64_t>(fid);
      ++sequence;
      const OGRGeometry* g = feature->GetGeometryRef();
      if (!g || g->IsEmpty()) continue;
      const auto where = [&] { return out_.path + ": layer '" + name + "' feature " + std::to_string(id); };
      if (!g->Is3D()) {
        throw Error(where() + ": " + OGRGeometryTypeToName(g->getGeometryType()) +
                    " has no Z coordinates; a terrain needs heights");
      }
      std::uint32_t material = layerMaterial;
      if (field >= 0) {
        material = builder_.material(feature->IsFieldSetAndNotNull(field) ? feature->GetFieldAsString(field) : "");
      }
      const std::uint32_t object = builder_.object(name + ":" + std::to_string(id));
      addGeometry(*g, material, object, id, where);
    }
  }

  void addGeometry(const OGRGeometry& g, std::uint32_t material, std::uint32_t object, std::uint64_t id,
                   const Builder::Where& where) {
    switch (wkbFlatten(g.getGeometryType())) {
      case wkbPolygon:
      case wkbTriangle:
        addPolygon(*g.toPolygon(), material, object, id, where);
        return;
      case wkbCurvePolygon: {
        // Arcs become line segments, as GDAL's default stroking does.
        std::unique_ptr<OGRGeometry> linear(g.getLinearGeometry());
        if (linear) addGeometry(*linear, material, object, id, where);
        return;
      }
      case wkbMultiPolygon:
      case wkbMultiSurface:
      case wkbGeometryCollection:
        for (const OGRGeometry* part : *g.toGeometryCollection()) addGeometry(*part, material, object, id, where);
        return;
      case wkbPolyhedralSurface:
      case wkbTIN: {
        // Each patch is a polygon; patches share corners, which Builder joins into shared vertices.
        const OGRPolyhedralSurface* s = g.toPolyhedralSurface();
        for (int i = 0; i < s->getNumGeometries(); ++i) addPolygon(*s->getGeometryRef(i), material, object, id, where);
        return;
      }
      default:
        throw Error(where() + ": " + OGRGeometryTypeToName(g.getGeometryType()) +
                    " is not a surface; only polygons, TINs and polyhedral surfaces make terrain");
    }
  }

  void addPolygon(const OGRPolygon& polygon, std::uint32_t material, std::uint32_t object, std::uint64_t id,
                  const Builder::Where& where) {
    std::vector<std::vector<std::uint32_t>> rings;
    for (const OGRLinearRing* ring : polygon) {
      std::vector<std::uint32_t> r;
      r.reserve(static_cast<std::size_t>(ring->getNumPoints()));
      for (int i = 0; i < ring->getNumPoints(); ++i) {
        const Eigen::Vector3d p(ring->getX(i), ring->getY(i), ring->getZ(i));
        if (!p.allFinite()) throw Error(where() + ": a non-finite coordinate");
        r.push_back(builder_.vertex(p));
      }
      rings.push_back(std::move(r));
    }
    if (rings.empty()) return;
    builder_.addFace(std::move(rings), material, object, id, where);
  }

  MeshFile& out_;
  const MeshFileOptions& options_;
  Builder builder_;
};

}  // namespace

void readOgr(MeshFile& out, const MeshFileOptions& options) {
  const QuietGdalErrors quietChild;
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(out.path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
  if (!ds) throw Error(out.path + ": cannot open as a vector dataset" + gdalMessage());
  OgrReader reader(out, options);
  reader.read(*ds);
}

}  // namespace qota::detail
