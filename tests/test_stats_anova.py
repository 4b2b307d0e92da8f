"""rm_anova against R (car::Anova univariate tests, Mauchly, GG/HF; afex pes/ges) and its input checks."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from analysis import rm_anova
from analysis.stats.design import prepare_design
from appeal.errors import AppealInputError

DATA = __import__("pathlib").Path(__file__).parent / "data"
NAN = float("nan")

# ---- produced by: Rscript tests/r_reference/anova_reference.R   (R 4.2.2, car 3.1.1, afex 1.2.1)
# aov_ez(id, dv, data, within, between, type = 3, fun_aggregate = mean) ; summary(fit$Anova,
# multivariate = FALSE) for SS / F / p / Mauchly / GG / HF and anova(fit, es = c("pes", "ges")).
# Data: tests/data/stats_*.csv written by the same script (set.seed).
R_WITHIN2 = {
    "A": {"SS": 29.312500000000025, "error_SS": 19.6875, "num_df": 2, "den_df": 14, "F": 10.422222222222231, "p": 0.0016902908391645932, "mauchly_W": 0.96196187116822052, "mauchly_p": 0.89017127389984207, "gg_eps": 0.96335574987540373, "hf_eps": 1.3219918399424355, "p_gg": 0.0019736644168726527, "p_hf": 0.0016902908391645932, "pes": 0.59821428571428592, "ges": 0.21212121212121227},
    "B": {"SS": 12.03125, "error_SS": 21.052083333333329, "num_df": 3, "den_df": 21, "F": 4.0004948045522024, "p": 0.021239947472211518, "mauchly_W": 0.83468293007372907, "mauchly_p": 0.96045589297587863, "gg_eps": 0.90998736983004647, "hf_eps": 1.5487526016271618, "p_gg": 0.025523379090546493, "p_hf": 0.021239947472211518, "pes": 0.3636649874055416, "ges": 0.099508917032825023},
    "A:B": {"SS": 5.4374999999999956, "error_SS": 26.229166666666661, "num_df": 6, "den_df": 42, "F": 1.4511517077045264, "p": 0.21845951430859087, "mauchly_W": 0.017302817368156045, "mauchly_p": 0.60568867021721484, "gg_eps": 0.51633085702633341, "hf_eps": 0.97316736640450152, "p_gg": 0.25518469375540509, "p_hf": 0.22038093456745964, "pes": 0.1717105263157894, "ges": 0.047566976489885143},
}

R_WITHIN3 = {
    "A": {"SS": 78.577045155135252, "error_SS": 2.0546244298792957, "num_df": 1, "den_df": 5, "F": 191.21997191416503, "p": 3.5517266771585981e-05, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.97451839406955365, "ges": 0.17600663773341965},
    "B": {"SS": 35.463567992680865, "error_SS": 5.5025998629855684, "num_df": 2, "den_df": 10, "F": 32.224374728057406, "p": 4.3723303178092699e-05, "mauchly_W": 0.80227106880673948, "mauchly_p": 0.64363886784430824, "gg_eps": 0.83491345491982971, "hf_eps": 1.2039856851182262, "p_gg": 0.00016113606795531551, "p_hf": 4.3723303178092699e-05, "pes": 0.86567940935133258, "ges": 0.087926891391030257},
    "C": {"SS": 27.879574762581811, "error_SS": 15.656815993007305, "num_df": 3, "den_df": 15, "F": 8.9033347441246899, "p": 0.0012491502890665364, "mauchly_W": 0.20224435759697643, "mauchly_p": 0.33318316823226735, "gg_eps": 0.64033121478105004, "hf_eps": 1.0312809573081365, "p_gg": 0.0068239848707584254, "p_hf": 0.0012491502890665364, "pes": 0.64037404752029625, "ges": 0.070448121667065614},
    "A:B": {"SS": 0.9007990500259262, "error_SS": 7.178036182774818, "num_df": 2, "den_df": 10, "F": 0.62746900899411717, "p": 0.55371267086553111, "mauchly_W": 0.80738491629054254, "mauchly_p": 0.65187040305348642, "gg_eps": 0.8384935036119483, "hf_eps": 1.2130440147043042, "p_gg": 0.53053427095586303, "p_hf": 0.55371267086553111, "pes": 0.11150110431372669, "ges": 0.002442729615198788},
    "A:C": {"SS": 2.7981520743392618, "error_SS": 5.0757299760859631, "num_df": 3, "den_df": 15, "F": 2.756403598617942, "p": 0.078836163223392819, "mauchly_W": 0.41581959188708667, "mauchly_p": 0.67389937299027713, "gg_eps": 0.76253279587124412, "hf_eps": 1.4409850262263417, "p_gg": 0.10069233661438609, "p_hf": 0.078836163223392819, "pes": 0.35537134750299554, "ges": 0.0075490103891637031},
    "B:C": {"SS": 0.43381091984615089, "error_SS": 11.768036671910444, "num_df": 6, "den_df": 30, "F": 0.18431745750828174, "p": 0.97897032069942225, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.035552887919959579, "ges": 0.0011778724796890538},
    "A:B:C": {"SS": 3.7173276197784033, "error_SS": 16.878592346392509, "num_df": 6, "den_df": 30, "F": 1.1011959834947118, "p": 0.38466148674724016, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.18048854461874811, "ges": 0.01000400536776164},
}

R_WITHIN4 = {
    "character": {"SS": 0.90000000000000391, "error_SS": 6.3916666666666657, "num_df": 1, "den_df": 9, "F": 1.2672750977835781, "p": 0.2894009674306367, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.12342857142857191, "ges": 0.0024229371382420354},
    "shape": {"SS": 60.543055555555569, "error_SS": 41.762499999999982, "num_df": 2, "den_df": 18, "F": 13.047291230170616, "p": 0.00031476427495543118, "mauchly_W": 0.33498974175884155, "mauchly_p": 0.012592908046163422, "gg_eps": 0.60059690025955448, "hf_eps": 0.641889139767155, "p_gg": 0.0031327967065759789, "p_hf": 0.0024640186010953589, "pes": 0.59178658702145015, "ges": 0.14044080454400479},
    "material": {"SS": 23.343055555555562, "error_SS": 13.670833333333331, "num_df": 2, "den_df": 18, "F": 15.367570862541914, "p": 0.00012790055990860298, "mauchly_W": 0.70302530589753154, "mauchly_p": 0.24427770558326464, "gg_eps": 0.77102506667797333, "hf_eps": 0.89974467337083719, "p_gg": 0.00057620930919858367, "p_hf": 0.00024674274294451753, "pes": 0.63065666041275803, "ges": 0.059262419650003721},
    "expression": {"SS": 12.469444444444475, "error_SS": 3.6833333333333362, "num_df": 1, "den_df": 9, "F": 30.468325791855253, "p": 0.00037057351326646201, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.77196904557179746, "ges": 0.032555643389152067},
    "character:shape": {"SS": 0.1291666666666651, "error_SS": 15.870833333333335, "num_df": 2, "den_df": 18, "F": 0.073247571541085993, "p": 0.92964627752853435, "mauchly_W": 0.97429772282846216, "mauchly_p": 0.90108705360415342, "gg_eps": 0.97494177624094325, "hf_eps": 1.2410316662910628, "p_gg": 0.92594375837977194, "p_hf": 0.92964627752853435, "pes": 0.0080729166666665686, "ges": 0.00034845947191528644},
    "character:material": {"SS": 0.38750000000000351, "error_SS": 4.8208333333333302, "num_df": 2, "den_df": 18, "F": 0.72342264477096641, "p": 0.49866640795437045, "mauchly_W": 0.79163395333653408, "mauchly_p": 0.39273323201467847, "gg_eps": 0.8275638021783176, "hf_eps": 0.99057378125435447, "p_gg": 0.47636977044807693, "p_hf": 0.49754930228573435, "pes": 0.07440000000000066, "ges": 0.0010446503791070021},
    "shape:material": {"SS": 6.7152777777777661, "error_SS": 19.145833333333332, "num_df": 4, "den_df": 36, "F": 3.1566920565832373, "p": 0.025326636259160207, "mauchly_W": 0.37580458035331454, "mauchly_p": 0.62340964577489077, "gg_eps": 0.70571080040848344, "hf_eps": 1.061509075796695, "p_gg": 0.04457360250904855, "p_hf": 0.025326636259160207, "pes": 0.25966702470461833, "ges": 0.017799882929415246},
    "character:expression": {"SS": 0.10000000000000002, "error_SS": 3.0527777777777785, "num_df": 1, "den_df": 9, "F": 0.29481346678798903, "p": 0.60033878944887908, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.031718061674008806, "ges": 0.00026979630379063814},
    "shape:expression": {"SS": 2.5597222222222213, "error_SS": 10.662499999999996, "num_df": 2, "den_df": 18, "F": 2.1606096131301289, "p": 0.14420865622727544, "mauchly_W": 0.49317798534754359, "mauchly_p": 0.059158169674070067, "gg_eps": 0.66364838731842302, "hf_eps": 0.73461512945686125, "p_gg": 0.16579123966532147, "p_hf": 0.16121767776918511, "pes": 0.19359243697478992, "ges": 0.0068605079679421067},
    "material:expression": {"SS": 0.15138888888888835, "error_SS": 9.4458333333333329, "num_df": 2, "den_df": 18, "F": 0.14424349360388128, "p": 0.86666757265099092, "mauchly_W": 0.68195166036910304, "mauchly_p": 0.2162790057563499, "gg_eps": 0.75869751505474936, "hf_eps": 0.88030507785096734, "p_gg": 0.81006990589419847, "p_hf": 0.84154122126509234, "pes": 0.015774240231548425, "ges": 0.00040838500590097457},
    "character:shape:material": {"SS": 2.1208333333333398, "error_SS": 19.129166666666663, "num_df": 4, "den_df": 36, "F": 0.99782182531039321, "p": 0.42138430531263849, "mauchly_W": 0.16709887565023088, "mauchly_p": 0.16389145167173991, "gg_eps": 0.5525996719001216, "hf_eps": 0.74024916747651825, "p_gg": 0.39363528756377963, "p_hf": 0.40826083856778639, "pes": 0.099803921568627732, "ges": 0.0056909023825762418},
    "character:shape:expression": {"SS": 0.82916666666666583, "error_SS": 8.1430555555555557, "num_df": 2, "den_df": 18, "F": 0.91642503837625688, "p": 0.41781726867753122, "mauchly_W": 0.46310187568096828, "mauchly_p": 0.045994527317633503, "gg_eps": 0.65066121441398717, "hf_eps": 0.71526727716972838, "p_gg": 0.38501500790925836, "p_hf": 0.39250386182208263, "pes": 0.092414860681114472, "ges": 0.0022326687684419543},
    "character:material:expression": {"SS": 3.679166666666668, "error_SS": 6.5013888888888882, "num_df": 2, "den_df": 18, "F": 5.0931424909207461, "p": 0.017664933154801749, "mauchly_W": 0.33195323735048071, "mauchly_p": 0.012142486623634496, "gg_eps": 0.59950357651340891, "hf_eps": 0.64030769712501201, "p_gg": 0.040867289535798226, "p_hf": 0.037491606966028039, "pes": 0.36139154160982273, "ges": 0.0098313199354228189},
    "shape:material:expression": {"SS": 1.0319444444444459, "error_SS": 13.245833333333332, "num_df": 4, "den_df": 36, "F": 0.70116388801510021, "p": 0.59627623607632363, "mauchly_W": 0.29035812978952458, "mauchly_p": 0.43762084833488624, "gg_eps": 0.67107960550471624, "hf_eps": 0.98339284182729492, "p_gg": 0.54561627776622146, "p_hf": 0.59411400318668228, "pes": 0.072276264591439779, "ges": 0.0027771651983449185},
    "character:shape:material:expression": {"SS": 0.8541666666666704, "error_SS": 21.090277777777786, "num_df": 4, "den_df": 36, "F": 0.3645044451761621, "p": 0.83224145906797897, "mauchly_W": 0.27687110514681756, "mauchly_p": 0.40655135861383718, "gg_eps": 0.75181438982501914, "hf_eps": 1.1711072130492739, "p_gg": 0.77960332958716916, "p_hf": 0.83224145906797897, "pes": 0.038924050632911537, "ges": 0.0022998305978437789},
}

R_OBK = {
    "treatment": {"SS": 179.73033252230337, "error_SS": 228.0555555555556, "num_df": 2, "den_df": 10, "F": 3.9404945010980024, "p": 0.054706926926519829, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.4407468178202068, "ges": 0.27790614338644015},
    "gender": {"SS": 83.448275862068954, "error_SS": 228.0555555555556, "num_df": 1, "den_df": 10, "F": 3.6591205006510128, "p": 0.084800253861640307, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.26788844131484263, "ges": 0.15160057633276949},
    "treatment:gender": {"SS": 130.24128142741287, "error_SS": 228.0555555555556, "num_df": 2, "den_df": 10, "F": 2.8554726744134364, "p": 0.10446923402377165, "mauchly_W": NAN, "mauchly_p": NAN, "gg_eps": NAN, "hf_eps": NAN, "p_gg": NAN, "p_hf": NAN, "pes": 0.36350106387794839, "ges": 0.21807146538185512},
    "phase": {"SS": 129.51149425287349, "error_SS": 80.2777777777778, "num_df": 2, "den_df": 20, "F": 16.132919699319874, "p": 6.7316365577054703e-05, "mauchly_W": 0.74927263801918054, "mauchly_p": 0.27282202608020856, "gg_eps": 0.79953475905113813, "hf_eps": 0.92785940395041788, "p_gg": 0.00028136812441584096, "p_hf": 0.00011247429005463222, "pes": 0.61734088211122251, "ges": 0.21711483433372183},
    "treatment:phase": {"SS": 77.885239253852347, "error_SS": 80.2777777777778, "num_df": 4, "den_df": 20, "F": 4.8509837597555077, "p": 0.0067227320954524571, "mauchly_W": 0.74927263801918054, "mauchly_p": 0.27282202608020856, "gg_eps": 0.79953475905113813, "hf_eps": 0.92785940395041788, "p_gg": 0.012690904360151882, "p_hf": 0.0084387755019298197, "pes": 0.49243647924518608, "ges": 0.14293879452580838},
    "gender:phase": {"SS": 2.2701149425287364, "error_SS": 80.2777777777778, "num_df": 2, "den_df": 20, "F": 0.28278248419043073, "p": 0.75664733892741154, "mauchly_W": 0.74927263801918054, "mauchly_p": 0.27282202608020856, "gg_eps": 0.79953475905113813, "hf_eps": 0.92785940395041788, "p_gg": 0.70895992688496368, "p_hf": 0.74085677643827874, "pes": 0.02750058018101648, "ges": 0.0048375442420976579},
    "treatment:gender:phase": {"SS": 10.221005677210062, "error_SS": 80.2777777777778, "num_df": 4, "den_df": 20, "F": 0.63660242972242587, "p": 0.64236948890534717, "mauchly_W": 0.74927263801918054, "mauchly_p": 0.27282202608020856, "gg_eps": 0.79953475905113813, "hf_eps": 0.92785940395041788, "p_gg": 0.6116208917343795, "p_hf": 0.63199753131429803, "pes": 0.11294080745619935, "ges": 0.021417761489156868},
    "hour": {"SS": 104.28544061302678, "error_SS": 62.499999999999986, "num_df": 4, "den_df": 40, "F": 16.685670498084288, "p": 4.0266433963377072e-08, "mauchly_W": 0.066066271643566113, "mauchly_p": 0.0075967723832692088, "gg_eps": 0.46028150225699316, "hf_eps": 0.55928018129414558, "p_gg": 9.762880671457388e-05, "p_hf": 2.300914306289096e-05, "pes": 0.6252670510670556, "ges": 0.18254524480988285},
    "treatment:hour": {"SS": 1.1666666666666679, "error_SS": 62.499999999999986, "num_df": 8, "den_df": 40, "F": 0.093333333333333449, "p": 0.99924462371938882, "mauchly_W": 0.066066271643566113, "mauchly_p": 0.0075967723832692088, "gg_eps": 0.46028150225699316, "hf_eps": 0.55928018129414558, "p_gg": 0.97862266260083142, "p_hf": 0.98866174857229794, "pes": 0.018324607329842955, "ges": 0.0024919900320398741},
    "gender:hour": {"SS": 2.8141762452107284, "error_SS": 62.499999999999986, "num_df": 4, "den_df": 40, "F": 0.45026819923371669, "p": 0.77155907058906203, "mauchly_W": 0.066066271643566113, "mauchly_p": 0.0075967723832692088, "gg_eps": 0.46028150225699316, "hf_eps": 0.55928018129414558, "p_gg": 0.6284343650929729, "p_hf": 0.66455413156586585, "pes": 0.043086760133747889, "ges": 0.0059899772878328848},
    "treatment:gender:hour": {"SS": 7.7554744525547372, "error_SS": 62.499999999999986, "num_df": 8, "den_df": 40, "F": 0.62043795620437914, "p": 0.75548444990407859, "mauchly_W": 0.066066271643566113, "mauchly_p": 0.0075967723832692088, "gg_eps": 0.46028150225699316, "hf_eps": 0.55928018129414558, "p_gg": 0.64136246182513057, "p_hf": 0.669297614466416, "pes": 0.11038961038961032, "ges": 0.016335724114603736},
    "phase:hour": {"SS": 11.346743295019168, "error_SS": 96.166666666666657, "num_df": 8, "den_df": 80, "F": 1.1799039821510402, "p": 0.32158661418336798, "mauchly_W": 0.0047799213541128774, "mauchly_p": 0.44939415321841614, "gg_eps": 0.44950125773181027, "hf_eps": 0.73306077623372412, "p_gg": 0.33452117985393259, "p_hf": 0.32965900331266251, "pes": 0.10553793521257271, "ges": 0.023720749548452744},
    "treatment:phase:hour": {"SS": 6.6411192214111949, "error_SS": 96.166666666666657, "num_df": 16, "den_df": 80, "F": 0.34529216055864104, "p": 0.99012456565671803, "mauchly_W": 0.0047799213541128774, "mauchly_p": 0.44939415321841614, "gg_eps": 0.44950125773181027, "hf_eps": 0.73306077623372412, "p_gg": 0.93037247963736014, "p_hf": 0.9752254493521717, "pes": 0.064597434562408323, "ges": 0.014021416114226129},
    "gender:phase:hour": {"SS": 8.9559386973180128, "error_SS": 96.166666666666657, "num_df": 8, "den_df": 80, "F": 0.93129345206079872, "p": 0.4956119229639907, "mauchly_W": 0.0047799213541128774, "mauchly_p": 0.44939415321841614, "gg_eps": 0.44950125773181027, "hf_eps": 0.73306077623372412, "p_gg": 0.44907768058652586, "p_hf": 0.4780340627232752, "pes": 0.08519517439953353, "ges": 0.01881673904906038},
    "treatment:gender:phase:hour": {"SS": 14.154501216544999, "error_SS": 96.166666666666657, "num_df": 16, "den_df": 80, "F": 0.73593593846854422, "p": 0.74956163945628196, "mauchly_W": 0.0047799213541128774, "mauchly_p": 0.44939415321841614, "gg_eps": 0.44950125773181027, "hf_eps": 0.73306077623372412, "p_gg": 0.64634490399218714, "p_hf": 0.70801216161904046, "pes": 0.12830267742931489, "ges": 0.029417788217208682},
}

CASES = {
    "within2_likert": ("stats_within2_likert.csv", "rating", ["A", "B"], [], R_WITHIN2),
    "within3_continuous": ("stats_within3_cont.csv", "y", ["A", "B", "C"], [], R_WITHIN3),
    "within4_likert_repeated_trials": ("stats_within4_likert_reps.csv", "appeal",
                                       ["character", "shape", "material", "expression"], [], R_WITHIN4),
    "mixed_obk_long": ("stats_obk_long.csv", "value", ["phase", "hour"], ["treatment", "gender"], R_OBK),
}


SINGULAR = {("within3_continuous", "B:C"), ("within3_continuous", "A:B:C")}


def _load(name):
    return pd.read_csv(DATA / name)


@pytest.mark.parametrize("case", list(CASES))
def test_agrees_with_r(case):
    fname, dv, within, between, ref = CASES[case]
    table = rm_anova(_load(fname), dv, "id", within, between, aggregate="mean").set_index("effect")
    assert list(table.index) == list(ref)  # names and the car/afex order
    for effect, values in ref.items():
        for col, expected in values.items():
            got = table.loc[effect, col]
            if math.isnan(expected):
                # car leaves sphericity undefined for 1-df and singular effects; so do we,
                # except that singular effects get ε from the trace formula (tested below)
                if (case, effect) not in SINGULAR or col in ("mauchly_W", "mauchly_p"):
                    assert math.isnan(got), (effect, col, got)
                continue
            assert got == pytest.approx(expected, rel=1e-6, abs=0), (effect, col)


def test_singular_effects_use_trace_epsilon():
    """B:C has 6 df with 5 error df: no Mauchly (as car), GG from the trace formula."""
    df = _load("stats_within3_cont.csv")
    table = rm_anova(df, "y", "id", ["A", "B", "C"]).set_index("effect")
    row = table.loc["B:C"]
    assert math.isnan(row.mauchly_W) and math.isnan(row.mauchly_p)
    # independent: GG = (sum λ)² / (d Σ λ²) from the eigenvalues of the covariance of the
    # subjects' B:C interaction contrasts (Helmert basis here, any orthonormal basis works)
    wide = df.pivot_table(index="id", columns=["B", "C"], values="y", aggfunc="mean").to_numpy()
    from scipy.linalg import helmert

    basis = np.kron(helmert(3, full=False).T, helmert(4, full=False).T)  # (12, 6)
    z = wide @ basis
    lam = np.linalg.eigvalsh(np.cov(z, rowvar=False))
    gg = lam.sum() ** 2 / (6 * (lam**2).sum())
    assert row.gg_eps == pytest.approx(gg, rel=1e-10)
    assert 1 / 6 <= row.gg_eps <= 5 / 6 + 1e-12  # rank 5 of 6


def test_pingouin_cross_check_two_way():
    import pingouin as pg

    df = _load("stats_within2_likert.csv")
    ours = rm_anova(df, "rating", "id", ["A", "B"]).set_index("effect")
    theirs = pg.rm_anova(df, dv="rating", within=["A", "B"], subject="id", correction=True).set_index("Source")
    for eff in ("A", "B", "A * B"):
        mine = ours.loc[eff.replace(" * ", ":")]
        assert mine.F == pytest.approx(theirs.loc[eff, "F"], rel=1e-9)
        assert mine.gg_eps == pytest.approx(theirs.loc[eff, "eps"], rel=1e-9)


def test_row_order_does_not_matter():
    df = _load("stats_obk_long.csv")
    a = rm_anova(df, "value", "id", ["phase", "hour"], ["treatment", "gender"])
    b = rm_anova(df.sample(frac=1, random_state=3), "value", "id", ["phase", "hour"], ["treatment", "gender"])
    pd.testing.assert_frame_equal(a, b)


def test_factor_order_names_effects_in_given_order():
    df = _load("stats_within2_likert.csv")
    t = rm_anova(df, "rating", "id", ["B", "A"])
    assert list(t.effect) == ["B", "A", "B:A"]
    ref = rm_anova(df, "rating", "id", ["A", "B"]).set_index("effect")
    assert t.set_index("effect").loc["B:A", "F"] == pytest.approx(ref.loc["A:B", "F"], rel=1e-12)


# ---------------------------------------------------------------- bad input
def _small():
    return _load("stats_within2_likert.csv")


def _message(exc_info):
    return str(exc_info.value)


def test_missing_cell_lists_subjects_and_cells():
    df = _small()
    df = df[~((df.id == "s03") & (df.A == "a2") & (df.B == "b4"))]
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert "1 subject(s) miss cells of the within design: s03 (A=a2, B=b4)" in _message(e)


def test_drop_incomplete_reports_dropped():
    df = _small()
    df = df[~((df.id == "s03") & (df.A == "a2") & (df.B == "b4"))]
    t = rm_anova(df, "rating", "id", ["A", "B"], drop_incomplete=True)
    assert t.attrs["dropped_subjects"] == ["s03"] and t.attrs["n_subjects"] == 7
    full = rm_anova(_small()[lambda d: d.id != "s03"], "rating", "id", ["A", "B"])
    pd.testing.assert_frame_equal(t, full)


def test_repeated_rows_need_aggregate():
    df = _load("stats_within4_likert_reps.csv")
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "appeal", "id", ["character", "shape", "material", "expression"])
    msg = _message(e)
    assert "360 subject x cell combinations have more than one row" in msg
    assert "(e.g. subject sub-01, character=female, shape=s0, material=m0, expression=angry: 2 rows)" in msg
    assert "aggregate: mean" in msg


def test_non_numeric_values_name_rows():
    df = _small()
    df["rating"] = df["rating"].astype(object)
    df.loc[[2, 6], "rating"] = "seven"
    df.attrs["source"] = "ratings.csv"
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert _message(e) == "ratings.csv: rating: non-numeric values in rows 3, 7 (e.g. 'seven'); expected numbers"


def test_out_of_scale_values_name_rows():
    df = _small()
    df.loc[4, "rating"] = 9
    with pytest.raises(AppealInputError) as e:
        prepare_design(df, "rating", "id", ["A", "B"], scale=(1, 7), source="r.csv")
    assert _message(e) == "r.csv: rating: values outside the scale 1..7 in row 5 (e.g. 9)"


def test_one_level_factor():
    df = _small()
    df = df[df.A == "a1"]
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert _message(e) == "<data>: A: a factor needs at least 2 levels (got only 'a1')"


def test_zero_variance_dv():
    df = _small()
    df["rating"] = 4
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert "rating: the DV has zero variance (every value is 4)" in _message(e)


def test_unknown_column_suggests():
    with pytest.raises(AppealInputError) as e:
        rm_anova(_small(), "ratng", "id", ["A", "B"])
    assert _message(e) == "<data>: dv: column 'ratng' not found (did you mean 'rating'?)"


def test_between_factor_must_be_constant_per_subject():
    df = _load("stats_obk_long.csv")
    df.loc[0, "gender"] = "F" if df.loc[0, "gender"] == "M" else "M"
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "value", "id", ["phase", "hour"], ["treatment", "gender"])
    assert "subjects o01 have more than one level of a between factor" in _message(e)


def test_aggregate_must_be_mean_or_none():
    with pytest.raises(AppealInputError) as e:
        rm_anova(_small(), "rating", "id", ["A", "B"], aggregate="median")
    assert "aggregate: expected 'mean' or none (got 'median')" in _message(e)
