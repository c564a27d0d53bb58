# Builds assets/optics/solar_astm_g173.csv from pvlib 0.16.1's pvlib/data/ASTMG173.csv (values copied verbatim).
# Usage: python3 make_solar_csv.py path/to/pvlib/data/ASTMG173.csv solar_astm_g173.csv
import sys
src = open(sys.argv[1]).read().splitlines()
assert src[1].startswith("wavelength,extraterrestrial,global,direct")
with open(sys.argv[2], "w") as f:
    f.write("# ASTM G173-03 reference solar spectra (derived from SMARTS v2.9.2), 280-4000 nm.\n")
    f.write("# Source: PyPI package pvlib 0.16.1, file pvlib/data/ASTMG173.csv, values copied verbatim (BSD-3-Clause).\n")
    f.write("# extraterrestrial = top-of-atmosphere spectral irradiance at 1 AU on a plane normal to the beam;\n")
    f.write("# global_tilt = AM1.5 global on a 37 deg tilted plane; direct_circumsolar = AM1.5 direct + circumsolar.\n")
    f.write("# Units: wavelength in nm; irradiances in W m-2 nm-1. Grid: 0.5 nm below 400 nm, 1 nm to 1700 nm, 5 nm from 1705 nm.\n")
    f.write("wavelength_nm,extraterrestrial_w_m2_nm,global_tilt_w_m2_nm,direct_circumsolar_w_m2_nm\n")
    for line in src[2:]:
        if line.strip():
            assert len(line.split(",")) == 4
            f.write(line.strip() + "\n")
