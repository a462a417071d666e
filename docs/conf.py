# The qota manual: Sphinx with MyST (the pages are Markdown) and Breathe over Doxygen's XML of
# the public headers (docs/Doxyfile). Built by scripts/docs.sh with warnings as errors.
import os

project = "qota"
author = "the qota developers"
version = release = open(os.path.join(os.path.dirname(__file__), "..", "CMakeLists.txt")).read().split(
    "project(qota VERSION ", 1)[1].split()[0]
extensions = ["myst_parser", "breathe"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "README.md"]
myst_heading_anchors = 3
breathe_projects = {"qota": os.environ.get("QOTA_DOXYGEN_XML", "../build/docs/xml")}
breathe_default_project = "qota"
breathe_default_members = ("members",)
primary_domain = "cpp"
highlight_language = "none"
html_theme = "alabaster"
html_theme_options = {"description": "terrain following in generalized coordinates", "page_width": "1100px"}
