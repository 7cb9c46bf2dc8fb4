"""File formats: ThymioLoc CSVs, pose Parquet, the OpticalFlows_HsAnts layout, instances."""
