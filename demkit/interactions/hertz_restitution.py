"""The restitution coefficient of a Hertz impact with Tsuji damping, and its inverse, without a solver at run time.

The dimensionless impact (see :mod:`demkit.interactions.hertz`)

    x'' = -max(0, x^(3/2) + gamma sqrt(3/2) x^(1/4) x'),   x(0) = 0, x'(0) = 1,

leaves the contact at speed e(gamma): the restitution coefficient depends on gamma alone.
:func:`restitution_of_damping` integrates it (scipy's DOP853, relative tolerance 1e-11; about
25 ms). A scene calibrates its dashpot with :func:`damping_for_restitution`, which inverts a fit
of that solver instead of solving again: log e as a function of u = log gamma in 24 Chebyshev pieces
of degree 10 between gamma = exp(-21) and 1e4 (``TABLE``, made by :func:`fit_table`; the fit
matches the solver to 3e-11 in e, the solver's own accuracy). Solving cost 0.2 s and scipy's
import 0.25 s at the start of every run with a Hertz contact; the fit costs 0.2 ms. Below
gamma = exp(-21) (e within 1.3e-9 of 1), log e is linear in gamma, with the fit's slope at its end.
"""
from __future__ import annotations

import math

import numpy as np

_ROOT_3_2 = math.sqrt(1.5)
#: the fit's range of u = log gamma
U_LOW, U_HIGH = -21.0, math.log(1e4) + 0.01


def restitution_of_damping(gamma):
    """Restitution coefficient of a Hertz impact with Tsuji damping constant ``gamma``, solved."""
    from scipy.integrate import solve_ivp
    if gamma == 0.0:
        return 1.0

    def rhs(t, y):
        x = max(y[0], 0.0)
        f = x ** 1.5 + gamma * _ROOT_3_2 * x ** 0.25 * y[1]
        return [y[1], -max(f, 0.0)]

    def ended(t, y):
        return y[0] if t > 1e-9 else 1.0

    ended.terminal, ended.direction = True, -1
    span = 50.0 * (1.0 + gamma)
    sol = solve_ivp(rhs, (0.0, span), [0.0, 1.0], events=ended, method="DOP853", rtol=1e-11, atol=1e-13)
    if not sol.t_events[0].size:  # the sphere came to rest inside the contact
        return 0.0
    return -float(sol.y_events[0][0][1])


def fit_table(pieces=24, degree=10):
    """Chebyshev coefficients of log e(u) on ``pieces`` equal pieces of [U_LOW, U_HIGH], from the
    solver at each piece's Chebyshev nodes (about 6 s). Prints as ``TABLE`` is written below."""
    edges = np.linspace(U_LOW, U_HIGH, pieces + 1)
    nodes = np.cos(np.pi * (np.arange(degree + 1) + 0.5) / (degree + 1))
    table = []
    for a, b in zip(edges[:-1], edges[1:]):
        u = 0.5 * (a + b) + 0.5 * (b - a) * nodes
        f = [math.log(restitution_of_damping(math.exp(v))) for v in u]
        table.append(tuple(float(c) for c in np.polynomial.chebyshev.chebfit(nodes, f, degree)))
    return table


def _piece(u):
    """(index of the piece holding u, u mapped to [-1, 1] in it)."""
    k = min(max(int((u - U_LOW) / _WIDTH), 0), len(TABLE) - 1)
    a = U_LOW + k * _WIDTH
    return k, (2.0 * (u - a) - _WIDTH) / _WIDTH


def fitted_restitution(gamma):
    """e(gamma) from the fit (gamma in (0, 1e4]; linear below exp(U_LOW))."""
    if gamma == 0.0:
        return 1.0
    u = math.log(gamma)
    if u < U_LOW:
        return math.exp(_LOW_SLOPE * gamma)
    k, x = _piece(u)
    return math.exp(np.polynomial.chebyshev.chebval(x, TABLE[k]))


def damping_for_restitution(restitution):
    """The Tsuji damping constant gamma that gives this restitution coefficient (0 < e <= 1)."""
    if restitution == 1.0:
        return 0.0
    target = math.log(restitution)
    if target < _EDGE_VALUES[-1]:
        raise ValueError(f"restitution {restitution} is too small to calibrate (needs gamma > 1e4)")
    if target > _EDGE_VALUES[0]:  # e within 1.3e-9 of 1: the linear law
        return target / _LOW_SLOPE
    # the piece whose values bracket the target (log e decreases with u), then Newton in it
    k = int(np.searchsorted(-_EDGE_VALUES, -target, side="right")) - 1
    k = min(max(k, 0), len(TABLE) - 1)
    c = TABLE[k]
    dc = np.polynomial.chebyshev.chebder(c)
    high, low = _EDGE_VALUES[k], _EDGE_VALUES[k + 1]
    x = -1.0 + 2.0 * (high - target) / (high - low) if high != low else 0.0
    for _ in range(50):
        step = (np.polynomial.chebyshev.chebval(x, c) - target) / np.polynomial.chebyshev.chebval(x, dc)
        x = min(max(x - step, -1.0), 1.0)
        if abs(step) < 1e-15:
            break
    return math.exp(U_LOW + k * _WIDTH + 0.5 * _WIDTH * (x + 1.0))


#: Chebyshev coefficients of log e(u), u = log gamma, piece by piece (fit_table(24, 10))
TABLE = [
    (-2.7065499380023337e-09, -1.6194300287019117e-09, -2.507860208154341e-10, -2.610216709084018e-11,
     -2.0436326714201665e-12, -1.2828703511723398e-13, -4.7652073866474165e-15, 2.502752227142294e-15,
     7.708001358479786e-16, 1.3357411908777319e-15, 1.7274789963715234e-15),
    (-9.511343150527866e-09, -5.704535411464582e-09, -8.834124435820041e-10, -9.19402676083662e-11,
     -7.198045620792049e-12, -4.531569784725614e-13, -2.469574770907714e-14, 5.667573666806644e-16,
     9.584505010619866e-16, 1.3321090485855332e-15, 5.4560328979296826e-15),
    (-3.348148661126335e-08, -2.0094391131685344e-08, -3.1118231679613906e-09, -3.238666012356853e-10,
     -2.536120870780496e-11, -1.593227203599792e-12, -8.363828615551378e-14, -6.506828038208727e-15,
     1.0079829085928373e-15, 1.0420522458663973e-15, -1.1998118110233133e-15),
    (-1.1791683296385034e-07, -7.07827862057291e-08, -1.0961285575827292e-08, -1.1407082475593458e-09,
     -8.933025360424962e-11, -5.6364217799127825e-12, -2.896379872716968e-13, 1.7019747339081062e-16,
     -7.376651735334622e-15, -4.472058694384895e-15, 4.204557533566812e-15),
    (-4.1534012557720784e-07, -2.4933597452774837e-07, -3.862005425410288e-08, -4.025467654798993e-09,
     -3.159139891594272e-10, -1.6467963360825443e-11, 3.2855396642229202e-12, 3.6060945512491048e-12,
     3.148576965548169e-12, 2.7378454142846707e-12, 1.6882778450807984e-12),
    (-1.4630098417786505e-06, -8.782707805440689e-07, -1.3601576388662592e-07, -1.4153005945841333e-08,
     -1.1102511011189867e-09, -7.157714355963823e-11, -6.713107775244167e-12, 2.511980377490396e-13,
     3.2818392516378334e-12, 3.2025163703428927e-12, -1.957019899974564e-12),
    (-5.153476714164719e-06, -3.0937518289720072e-06, -4.790980534302788e-07, -4.985813198122871e-08,
     -3.903719808783542e-09, -2.4334481492131434e-10, -9.77451596214473e-12, 3.362886022575902e-13,
     -6.388519390439557e-15, 9.43152585827834e-13, 3.635848401224363e-12),
    (-1.8153200805187183e-05, -1.0897822213402143e-05, -1.6876946854594487e-06, -1.7567256985353788e-07,
     -1.3791144995233447e-08, -8.750531252570875e-10, -1.8055686358398652e-11, 1.2095340717533997e-11,
     3.12312288678471e-11, 3.1376000760271424e-11, -4.372610222635723e-12),
    (-6.394472623392713e-05, -3.8387154980283906e-05, -5.944511628229153e-06, -6.186749881874293e-07,
     -4.8424708724537515e-08, -3.042792927531096e-09, -1.822329103593044e-10, -7.401065448509438e-12,
     6.925081603700656e-12, 1.2547931701118256e-12, 2.1380409152358302e-11),
    (-0.00022523890006595506, -0.00013521094184344257, -2.0937046167581317e-05, -2.1786635017637464e-06,
     -1.7053792368852145e-07, -1.0691839289924724e-08, -5.49983968233493e-10, -3.641124338197566e-11,
     -1.7943134947815907e-11, -6.825770602366692e-12, -2.0801260802508582e-12),
    (-0.0007933039027584137, -0.0004761704497939954, -7.371751812398408e-05, -7.667577933011495e-06,
     -5.997109279962739e-07, -3.7509443991081284e-08, -1.9465080213730015e-09, -1.2051011073898016e-10,
     4.040347357201946e-11, -2.107645712905293e-11, -8.622644266216255e-12),
    (-0.0027930994476729728, -0.0016759038895151621, -0.00025925170736880004, -2.692377791235678e-05,
     -2.099348366168817e-06, -1.3059001514375262e-07, -6.750703137660784e-09, -3.035489719934653e-10,
     -3.4899413296191813e-11, 2.1585397657485084e-11, 1.0252561865292271e-11),
    (-0.009822197811684627, -0.005885838179310602, -0.0009080297682280016, -9.378776001177122e-05,
     -7.233564919765927e-06, -4.401294693689287e-07, -2.158564168675611e-08, -8.411034861237268e-10,
     -1.2892550704330167e-11, 2.7285376981012944e-12, 1.1682923552864416e-11),
    (-0.034395309175957116, -0.020517711759540883, -0.003135330785096234, -0.0003176670069271056,
     -2.3554105977283303e-05, -1.3173781499635344e-06, -5.291798737286642e-08, -1.0298039220766779e-09,
     1.1876348638825094e-10, 4.869299178382817e-11, 6.543664747176454e-11),
    (-0.11872098826318532, -0.06972353182607471, -0.010309189864716213, -0.0009755734355288367,
     -6.217929357677737e-05, -2.295322297103619e-06, 2.2776458122717192e-08, 1.0850470246977427e-08,
     9.638860938721468e-10, 2.6904559413238038e-11, -6.300892151557766e-11),
    (-0.3913513833555751, -0.21844081288537417, -0.028955436427778855, -0.00213530864794822,
     -5.8052570192715735e-05, 5.702296409588974e-06, 7.607549691989598e-07, 2.9372667859465198e-08,
     -2.0167330651792648e-09, -3.600455503521916e-10, 3.5247048249547024e-13),
    (-1.1421943617192238, -0.5529703272707593, -0.05308261196894003, -0.001172518645644274,
     0.00021533016395087248, 1.4870781635269955e-05, -9.881111483091536e-07, -1.5240620707352776e-07,
     1.506793725832563e-09, 1.3125165215916406e-09, 4.062180296449205e-11),
    (-2.6694952085736814, -0.9661416469245583, -0.04347072410244669, 0.0024998322865758286,
     0.0001121138466205979, -2.1579230605708704e-05, -1.4826916581368246e-07, 1.8076791200178189e-07,
     -4.08015333230217e-09, -1.5407981209452807e-09, 7.379332057619758e-11),
    (-4.851619958359704, -1.191281656382877, -0.014287862370537396, 0.0017695047198280063,
     -0.00012137216339791047, 9.240749221268204e-07, 7.12904565763752e-07, -6.688817293358149e-08,
     7.559409892254655e-10, 4.945249632040507e-10, 3.2128284514834565e-11),
    (-7.3014472008455185, -1.2488732582452147, -0.0025186019271528307, 0.0003992839147539332,
     -4.433910293843478e-05, 3.4459097044542074e-06, -1.6230391035400595e-07, -9.961429125913715e-10,
     1.0340815041244481e-09, 5.374766549962235e-10, 5.087108882305222e-10),
    (-9.810023271245866, -1.2579328115080677, -0.0003255556291905723, 5.6775336818108185e-05,
     -7.247923048563e-06, 7.4222902306224e-07, -4.908385991450417e-08, -4.26921368462774e-09,
     -1.26183713164332e-08, -2.1133989104363332e-08, -1.696147941635414e-08),
    (-12.327233830382879, -1.259046231661411, -3.6297717664414815e-05, 6.631753359107987e-06,
     -9.929956302287225e-07, 8.333613147401131e-08, -7.269393150617523e-08, -3.6480958622464555e-08,
     -1.0809409065152697e-07, -2.9168975931581427e-08, -7.553730977597464e-09),
    (-14.845473215748466, -1.2591672376492578, -3.877419740794578e-06, 7.448675304263699e-07,
     -2.402069814155602e-08, 4.899287724924451e-08, -1.4932664720612056e-07, -2.315645976221511e-09,
     1.3873594017915075e-07, -2.5155068658371662e-08, -9.293315041949417e-08),
    (-17.363822682859833, -1.2591794784547528, -3.4142753171969345e-07, 9.89356210499241e-08,
     -2.0440677913712192e-08, -1.5218331674465556e-08, 1.8365843932323633e-08, -7.182831858426576e-09,
     -4.441083201057669e-09, 1.5770239393199687e-08, -1.6522105917380848e-08),
]
#: the width of a piece in u
_WIDTH = (U_HIGH - U_LOW) / len(TABLE)
#: log e at the pieces' edges (decreasing)
_EDGE_VALUES = np.array([np.polynomial.chebyshev.chebval(-1.0, c) for c in TABLE]
                        + [np.polynomial.chebyshev.chebval(1.0, TABLE[-1])])
#: log e = _LOW_SLOPE gamma below gamma = exp(U_LOW)
_LOW_SLOPE = float(_EDGE_VALUES[0]) / math.exp(U_LOW)
