// qota sample on vector layers: points from any OGR layer, heights written to a layer of any OGR
// format with every input field kept (qota_tools.hpp, SampleOptions).
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "cancel.hpp"
#include "gdal_errors.hpp"
#include "qota/crs_transform.hpp"
#include "qota/atomic_file.hpp"
#include "qota/dem.hpp"
#include "qota/error.hpp"
#include "raster_output.hpp"
#include "sample_lines.hpp"
#include "text_output.hpp"

namespace qota::tools::sampling {
namespace {

// The column names a CSV's coordinates are found by (OGR matches them without regard to case).
constexpr const char* kCsvOpenOptions[] = {
    "X_POSSIBLE_NAMES=x,lon,long,longitude,easting", "Y_POSSIBLE_NAMES=y,lat,latitude,northing",
    "GEOM_POSSIBLE_NAMES=wkt,geom,geometry", "KEEP_GEOM_COLUMNS=YES", "AUTODETECT_TYPE=YES"};

std::unique_ptr<GDALDataset> openVector(const std::string& path, const std::vector<std::string>& options) {
  CPLStringList oo;
  for (const std::string& o : options) oo.AddString(o.c_str());
  return std::unique_ptr<GDALDataset>(
      GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, oo.List(), nullptr));
}

OGRLayer* layerOf(GDALDataset& ds, const SampleOptions& o) {
  if (o.layer.empty()) return ds.GetLayerCount() > 0 ? ds.GetLayer(0) : nullptr;
  OGRLayer* layer = ds.GetLayerByName(o.layer.c_str());
  if (!layer) throw Error(o.inputFile + ": no layer '" + o.layer + "'");
  return layer;
}

// From the layer's CRS (or --srs when it states none, or when given) to the source's.
std::unique_ptr<OGRCoordinateTransformation> transformFrom(OGRLayer& layer, const SampleOptions& o,
                                                           const std::string& sourceWkt) {
  OGRSpatialReference from;
  if (!o.srs.empty()) {
    from = *crsFromUser(o.srs, "--srs");
  } else if (const OGRSpatialReference* own = layer.GetSpatialRef()) {
    from = *own;
  } else {
    return nullptr;  // the layer states none: its coordinates are the source's
  }
  if (sourceWkt.empty()) {
    throw Error(o.source + ": the source has no CRS, so the points of " + o.inputFile + " (" +
                (from.GetName() ? from.GetName() : "a CRS") + ") cannot be placed on it");
  }
  OGRSpatialReference to;
  to.importFromWkt(sourceWkt.c_str());
  if (from.IsSame(&to)) return nullptr;
  return transformTo(from, sourceWkt, o.inputFile + ": no transformation from its CRS to the source's");
}

std::string featureName(const OGRFeature& f) {
  return f.GetFID() == OGRNullFID ? std::string("a feature") : "feature " + std::to_string(f.GetFID());
}

// A batch of features, their queries and answers.
struct Batch {
  std::vector<std::unique_ptr<OGRFeature>> features;
  std::vector<Query> queries;
  std::vector<std::size_t> of;        // queries[k] is features[of[k]]'s point
  std::vector<std::string> problems;  // per feature: why it has no query ("" when it has one)
};

}  // namespace

std::unique_ptr<GDALDataset> openPointLayer(const SampleOptions& o) {
  ensureGdalRegistered();
  std::unique_ptr<GDALDataset> ds;
  {
    detail::QuietGdalErrors quiet;  // (a text file is not a vector dataset, and says so)
    ds = openVector(o.inputFile, o.openOptions);
    if (ds && ds->GetDriver() && std::string(ds->GetDriver()->GetDescription()) == "CSV" && o.openOptions.empty()) {
      ds = openVector(o.inputFile, std::vector<std::string>(std::begin(kCsvOpenOptions), std::end(kCsvOpenOptions)));
    }
  }
  if (!ds) return nullptr;
  // A CSV is lines of text too, as qota sample has always read them: a layer only when a layer
  // is written for it (-o, no --header).
  const bool csv = std::string(ds->GetDriver()->GetDescription()) == "CSV";
  if (csv && (o.outputFile.empty() || o.header) && o.openOptions.empty() && o.layer.empty()) return nullptr;
  OGRLayer* layer = layerOf(*ds, o);
  if (!layer || layer->GetGeomType() == wkbNone) {
    if (!o.layer.empty() || !o.openOptions.empty()) {
      throw Error(o.inputFile + ": its layer has no geometry (a CSV needs x and y columns, or WKT)");
    }
    return nullptr;  // lines of text (a CSV without coordinate columns among them)
  }
  return ds;
}

bool sampleLayer(const SampleOptions& o, GDALDataset& in, const Surface& surface, const std::string& sourceWkt,
                 bool integerSource, std::ostream& err) {
  if (o.outputFile.empty()) {
    throw Error(o.inputFile +
                " is a vector layer: give -o OUT for the layer with heights (any OGR format, by "
                "extension or --of; /vsistdout/ with --of for a pipe)");
  }
  if (o.printWorld || o.header || o.swapXY) {
    throw Error(std::string(o.printWorld ? "--world"
                            : o.header   ? "--header"
                                         : "-w") +
                " applies to lines of text; a vector layer's points are in its CRS's x, y order and its fields "
                "are named");
  }
  OGRLayer& layer = *layerOf(in, o);
  const std::unique_ptr<OGRCoordinateTransformation> transform = transformFrom(layer, o, sourceWkt);
  OGRFeatureDefn* defn = layer.GetLayerDefn();
  if (defn->GetFieldIndex(o.field.c_str()) >= 0) {
    throw Error(o.inputFile + ": already has a field '" + o.field + "'; name the heights' field with --field");
  }

  // The output, staged: it appears complete or not at all (with its sidecar files).
  const std::string format = o.outputFormat.empty() ? vectorDriverForPath(o.outputFile) : o.outputFormat;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format.c_str());
  if (!driver || !driver->GetMetadataItem(GDAL_DCAP_VECTOR) || !driver->GetMetadataItem(GDAL_DCAP_CREATE)) {
    throw Error("--of " + format + ": not a GDAL vector driver that writes files");
  }
  const bool device = o.outputFile.rfind("/vsistdout", 0) == 0;
  OutputStage stage;
  const std::string target = device ? o.outputFile : stage.stage(o.outputFile).string();
  detail::GdalErrorLog errors;
  std::unique_ptr<GDALDataset> out(driver->Create(target.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!out) throw Error(o.outputFile + ": cannot create (" + errors.message() + ")");
  CPLStringList lco;
  const bool csvIn = std::string(in.GetDriver()->GetDescription()) == "CSV";
  if (format == "CSV" && !csvIn) lco.SetNameValue("GEOMETRY", "AS_XY");  // (a CSV keeps no geometry else)
  OGRLayer* written = out->CreateLayer(layer.GetName(), layer.GetSpatialRef(), layer.GetGeomType(), lco.List());
  if (!written) throw Error(o.outputFile + ": cannot create the layer (" + errors.message() + ")");
  for (int i = 0; i < defn->GetFieldCount(); ++i) {
    if (written->CreateField(defn->GetFieldDefn(i)) != OGRERR_NONE) {
      throw Error(o.outputFile + ": cannot create the field '" + defn->GetFieldDefn(i)->GetNameRef() + "' (" +
                  errors.message() + ")");
    }
  }
  OGRFieldDefn heightField(o.field.c_str(), OFTReal);
  if (written->CreateField(&heightField) != OGRERR_NONE) {
    throw Error(o.outputFile + ": cannot create the field '" + o.field + "' (" + errors.message() + ")");
  }
  const int heightAt = written->GetLayerDefn()->GetFieldIndex(o.field.c_str());
  const bool transaction = out->StartTransaction() == OGRERR_NONE;

  std::uint64_t failures = 0;
  constexpr std::uint64_t kMostMessages = 20;
  const auto fail = [&](const std::string& message) {
    if (++failures <= kMostMessages) err << "qota sample: " << o.inputFile << ": " << message << '\n';
  };
  constexpr std::size_t kBatch = 1 << 16;
  layer.ResetReading();
  for (bool more = true; more;) {
    throwIfCancelled();
    Batch b;
    while (b.features.size() < kBatch) {
      std::unique_ptr<OGRFeature> f(layer.GetNextFeature());
      if (!f) {
        more = false;
        break;
      }
      const OGRGeometry* g = f->GetGeometryRef();
      std::string problem;
      if (!g || g->IsEmpty()) {
        problem = featureName(*f) + ": no point";
      } else if (wkbFlatten(g->getGeometryType()) != wkbPoint) {
        problem = featureName(*f) + ": a " + std::string(OGRGeometryTypeToName(g->getGeometryType())) + ", not a point";
      } else {
        const OGRPoint* p = g->toPoint();
        if (o.queryZ && !p->Is3D()) {
          problem = featureName(*f) + ": no z (--query-z takes the query height from the point's z)";
        } else {
          b.of.push_back(b.features.size());
          b.queries.push_back({p->getX(), p->getY(), o.queryZ ? p->getZ() : 0.0});
        }
      }
      b.problems.push_back(problem);
      b.features.push_back(std::move(f));
    }
    if (transform && !b.queries.empty()) {
      std::vector<double> xs(b.queries.size()), ys(b.queries.size());
      std::vector<int> ok(b.queries.size());
      for (std::size_t k = 0; k < b.queries.size(); ++k) xs[k] = b.queries[k].x, ys[k] = b.queries[k].y;
      transform->Transform(xs.size(), xs.data(), ys.data(), nullptr, ok.data());
      for (std::size_t k = 0; k < b.queries.size(); ++k) {
        b.queries[k].x = ok[k] ? xs[k] : NAN, b.queries[k].y = ok[k] ? ys[k] : NAN;
        if (!ok[k])
          b.problems[b.of[k]] = featureName(*b.features[b.of[k]]) + ": cannot be transformed to the source's CRS";
      }
    }
    std::vector<Answer> answers(b.queries.size());
    surface(b.queries, o.queryZ, answers);
    std::vector<const Answer*> answerOf(b.features.size(), nullptr);
    for (std::size_t k = 0; k < b.queries.size(); ++k) answerOf[b.of[k]] = &answers[k];
    for (std::size_t i = 0; i < b.features.size(); ++i) {
      OGRFeature f(written->GetLayerDefn());
      f.SetFrom(b.features[i].get(), TRUE);
      f.SetFID(b.features[i]->GetFID());
      const Answer* a = answerOf[i];
      std::string problem = b.problems[i];
      if (problem.empty() && a && !a->problem.empty()) problem = featureName(*b.features[i]) + ": " + a->problem;
      if (problem.empty() && a && a->height) {
        f.SetField(heightAt, integerSource && o.precision < 0 ? withoutNoise(*a->height) : *a->height);
      } else {
        f.SetFieldNull(heightAt);
      }
      if (!problem.empty()) fail(problem);
      if (written->CreateFeature(&f) != OGRERR_NONE) {
        throw Error(o.outputFile + ": cannot write " + featureName(*b.features[i]) + " (" + errors.message() + ")");
      }
    }
  }
  if (transaction && out->CommitTransaction() != OGRERR_NONE) {
    throw Error(o.outputFile + ": cannot write (" + errors.message() + ")");
  }
  out.reset();  // (closed: a full disk shows here)
  if (errors.failed()) throw Error(o.outputFile + ": cannot write (" + errors.message() + ")");
  if (!device) stage.commit();
  if (failures > kMostMessages) {
    err << "qota sample: " << o.inputFile << ": " << failures - kMostMessages << " more features without a height ("
        << failures << " in all; the first " << kMostMessages << " are named above)\n";
  }
  return failures > 0;
}

}  // namespace qota::tools::sampling
