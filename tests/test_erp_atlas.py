"""Anatomical labels of MNI peaks from the offline atlases (AAL, Talairach Brodmann areas)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.erp.atlas import atlas_available, label_peaks, short_name
from analysis.erp.report import thesis_table

pytestmark = pytest.mark.skipif(not atlas_available(), reason="needs the atlases: pip install 'appeal-lab[atlas]'")


def test_planted_and_thesis_peaks_get_their_regions():
    t = label_peaks([[40, -55, -15], [-30, -85, 10],  # right fusiform, left middle occipital gyrus
                     [28, -90, 2], [-34, -90, 8]])  # thesis Table 7.1: Mid OG R, Mid OG L
    assert t["region"].tolist() == ["Fusiform_R", "Occipital_Mid_L", "Occipital_Mid_R", "Occipital_Mid_L"]
    assert t["area"].tolist() == ["Fusiform G R", "Mid OG L", "Mid OG R", "Mid OG L"]
    assert t["hemisphere"].tolist() == ["R", "L", "R", "L"]
    assert t.loc[0, "brodmann"] == "37" and t.loc[1, "brodmann"] == "19"
    far = label_peaks([[0.0, 0.0, 200.0]])
    assert far.loc[0, "region"] == "unlabelled" and far.loc[0, "brodmann"] == ""


def test_short_names_follow_table_7_1():
    assert short_name("Occipital_Mid_R") == "Mid OG R" and short_name("Occipital_Inf_L") == "Inf OG L"
    assert short_name("Frontal_Inf_Oper_R") == "Inf FG Oper R" and short_name("Lingual_R") == "Lingual G R"
    assert short_name("Precuneus_L") == "Precuneus L" and short_name("Vermis_4_5") == "Vermis 4 5"


def test_the_report_table_reads_like_table_7_1():
    table = pd.DataFrame({"component": ["N170"] * 3, "contrast": ["stylisation 5 > 0"] * 2 + ["stylisation 0 > 5"],
                          "n_voxels": [408, 86, 169], "volume_mm3": [3264.0, 688.0, 1352.0], "peak_t": [3.35, 2.70, 3.31],
                          "peak_p_uncorrected": [0.0004, 0.004, 0.0008], "x_mm": [28.0, -34.0, 18.0],
                          "y_mm": [-90.0, -90.0, -98.0], "z_mm": [2.0, 8.0, -14.0]})
    labels = label_peaks(table[["x_mm", "y_mm", "z_mm"]].to_numpy(float))
    text = thesis_table(table.assign(area=labels["area"], brodmann=labels["brodmann"]))
    lines = text.splitlines()
    assert lines[0].startswith("| Cluster voxels (mm³) | Peak t | Peak p-uncor | x (mm)")
    assert "| **N170: stylisation 5 > 0** |" in lines[2] and "| **N170: stylisation 0 > 5** |" in lines[5]
    assert lines[3] == "| 408 (3264) | 3.35 | < .001 | 28 | -90 | 2 | Mid OG R | 18 |"
    assert np.sum(["Mid OG L" in ln for ln in lines]) == 1
