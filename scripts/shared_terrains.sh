# Sourced by the measuring scripts: the shared terrains' folder (`CLIPSAT_DATA`, as the tests find it)
# and the six shared terrains, each with the arguments it needs (Puget Sound's PNG has no spacing).
DATA=${CLIPSAT_DATA:-../shared/data}
TERRAINS=("ps_height_1k.png --spacing 160" "n07_w006_3arc_v2.tif" "srtm_bigtujunga30m_utm11.tif"
  "aletsch_200m.tif" "lidar_pkg_dem_1m_400x400.tif" "N57E011.hgt")
