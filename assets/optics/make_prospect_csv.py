# Builds assets/optics/prospect_spectra.csv from prosail 2.0.5's data files (values copied verbatim).
# Usage: python3 make_prospect_csv.py path/to/prosail/package/dir prospect_spectra.csv
import sys
src = sys.argv[1]
p5 = [l.split() for l in open(src + "/prospect5_spectra.txt") if l.strip() and not l.startswith("#")]
pd = [l.split() for l in open(src + "/prospect_d_spectra.txt") if l.strip() and not l.startswith("#")]
assert len(p5) == 2101 and len(pd) == 2101
out = open(sys.argv[2], "w")
out.write("# PROSPECT-5 and PROSPECT-D refractive index and specific absorption coefficients, 400-2500 nm at 1 nm.\n")
out.write("# Source: PyPI package prosail 2.0.5 (J. Gomez-Dans), files prosail/prospect5_spectra.txt and\n")
out.write("# prosail/prospect_d_spectra.txt (dataSpec_PDB.m, 16 January 2017), values copied verbatim.\n")
out.write("# PROSPECT-5: Feret et al. 2008, Remote Sens. Environ. 112:3030. PROSPECT-D: Feret et al. 2017, Remote Sens. Environ. 193:204.\n")
out.write("# Units: n dimensionless; k_cab, k_car, k_anth in cm2/ug; k_brown arbitrary (per unit Cbrown); k_cw in cm-1; k_cm in cm2/g.\n")
out.write("# PROSPECT-5 has no anthocyanin term. See README.md in this folder for licence.\n")
out.write("wavelength_nm,p5_n,p5_k_cab_cm2_per_ug,p5_k_car_cm2_per_ug,p5_k_brown,p5_k_cw_per_cm,p5_k_cm_cm2_per_g,"
          "pd_n,pd_k_cab_cm2_per_ug,pd_k_car_cm2_per_ug,pd_k_anth_cm2_per_ug,pd_k_brown,pd_k_cw_per_cm,pd_k_cm_cm2_per_g\n")
for i in range(2101):
    wl = 400 + i
    a = p5[i]; b = pd[i]
    assert len(a) == 6 and len(b) == 8 and int(b[0]) == wl, (wl, a, b)
    # p5 columns: n, kab, kcar, kbrown, kw, km ; pd columns: wl, n, kab, kcar, kanth, kbrown, kw, km
    out.write(",".join([str(wl)] + a + b[1:]) + "\n")
