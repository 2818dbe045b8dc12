#pragma once
// Sparse nonlinear least squares over small blocks of variables: whitened factors' normal
// equations accumulated block by block into a sparsity pattern fixed once, a sparse Cholesky
// factorisation (Eigen's SimplicialLLT; the variables laid out in an AMD order of the block
// pattern, analysed once) or a dense one where the factor would fill in most of the triangle,
// Levenberg-Marquardt
// steps, robust losses by iterative reweighting, and marginal covariance blocks of chosen
// variables (columns of the inverse information matrix).
//
// Pure: Eigen only, no clocks, threads or random numbers.

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

namespace mapmesh {

// Robust losses of a factor's squared whitened residual s = |r|^2 (Triggs et al. 2000; the
// conventions of Ceres's LossFunction): rho(s) replaces s in the cost, and the factor is
// reweighted by rho'(s) at each linearisation (iteratively reweighted least squares).
enum class RobustLoss { kNone, kHuber, kCauchy };

struct RobustKernel {
  RobustLoss loss = RobustLoss::kNone;
  double scale = 1.0;  // c: the whitened residual norm at which the loss departs from the square

  // kNone: s. Huber: s up to c^2, then 2 c sqrt(s) - c^2. Cauchy: c^2 log(1 + s / c^2).
  double Rho(double s) const;
  // rho'(s): the weight iteratively reweighted least squares gives the factor.
  double Weight(double s) const;
};

// How BlockNormalEquations factorises H. kAuto: densely when the Cholesky factor of the block
// pattern (in its fill-reducing order) would hold at least kDenseFillShare of the triangle's
// entries, else sparsely. A simplicial sparse factorisation of a dense matrix is about five
// times slower than a dense one (Eigen, one core; 470 variables: 10 ms against 2 ms), and a
// join whose old submaps are summarised is mostly dense (each summary couples all its
// landmarks).
enum class Factorisation { kAuto, kSparse, kDense };
inline constexpr double kDenseFillShare = 0.3;

// The normal equations H dx = -g of a least-squares problem over blocks of variables, for
// factors that each couple a few of them: H = sum w J^T J, g = sum w J^T r over the factors'
// whitened residuals r and Jacobians J. The sparsity pattern is declared once (Couple, then
// Finalize) and reused at every linearisation.
class BlockNormalEquations {
 public:
  // Variables with these sizes (1-6), in this order.
  explicit BlockNormalEquations(std::vector<int> sizes, Factorisation factorisation = Factorisation::kAuto);

  int variables() const { return static_cast<int>(sizes_.size()); }
  int dim() const { return dim_; }
  int size(int var) const { return sizes_[static_cast<std::size_t>(var)]; }
  // Where a variable starts in H, g and a step: set by Finalize (a fill-reducing order, not the
  // variables' order).
  int offset(int var) const { return offsets_[static_cast<std::size_t>(var)]; }

  // Declares that a factor couples these variables (distinct); returns a handle for Add.
  // Factors over the same variables in the same order may share a handle.
  int Couple(const std::vector<int>& vars);
  // Builds the sparsity pattern and analyses it; call once, after every Couple.
  void Finalize();

  // Clears H and g (the pattern stays).
  void SetZero();
  // Adds w J^T J to H and w J^T r to g for a factor of coupling `handle`: J's columns are its
  // variables' blocks in Couple's order.
  void Add(int handle, const Eigen::Ref<const Eigen::MatrixXd>& j, const Eigen::Ref<const Eigen::VectorXd>& r,
           double w = 1.0);

  // Adds a factor given in information form over the variables of coupling `handle`: h to H
  // and g to the gradient (h square, g a vector, both in Couple's column order). A dense prior
  // from marginalisation (cost 1/2 d^T h d + g^T d about the current state) enters this way.
  void AddInformation(int handle, const Eigen::Ref<const Eigen::MatrixXd>& h,
                      const Eigen::Ref<const Eigen::VectorXd>& g);

  // Solves (H + lambda diag(H)) dx = -g; false when that matrix is not positive definite.
  bool Solve(double lambda, Eigen::VectorXd* dx);
  // The marginal covariance block (H^-1) of each of these variables, from H as last
  // accumulated; empty when H is not positive definite.
  std::vector<Eigen::MatrixXd> Marginals(const std::vector<int>& vars);
  // The joint covariance (H^-1) of these variables together, cross blocks included, in the
  // order given; empty when H is not positive definite or vars is empty.
  Eigen::MatrixXd JointMarginal(const std::vector<int>& vars);

  const Eigen::VectorXd& gradient() const { return g_; }
  // Non-zeros of H's upper triangle, and of its Cholesky factor after a Solve (fill-in).
  Eigen::Index nonzeros() const { return h_.nonZeros(); }
  // Entries of the Cholesky factor's lower triangle that the block pattern implies (symbolic,
  // set by Finalize), and whether H is factorised densely.
  Eigen::Index factor_entries() const { return factor_entries_; }
  bool dense() const { return dense_; }

 private:
  // A block of H between two variables a <= b: its values (size_a x size_b, column-major)
  // start at values_[offset].
  struct Block {
    int a, b, offset;
  };
  // For a coupling: the blocks its factors add to, with the column ranges of J they come from.
  struct Term {
    int block;
    int col_a, col_b;  // first columns in J of the block's variables a and b
  };
  struct Coupling {
    std::vector<int> vars;
    std::vector<int> cols;  // first column in J of each variable
    std::vector<Term> terms;
  };
  // Scatters the blocks' values into h_ and adds lambda diag(H) to its diagonal.
  void Assemble(double lambda);
  bool Factorise(double lambda);
  // The factor's entries implied by the block pattern with the variables in `layout`'s order
  // (a symbolic block elimination along the elimination tree).
  Eigen::Index SymbolicFactorEntries(const std::vector<int>& layout) const;
  // L^-1 times the unit columns of `vars` (in that order), into y (dim x their total size).
  void SolveUnitColumns(const std::vector<int>& vars, Eigen::MatrixXd* y) const;

  std::vector<int> sizes_, offsets_;
  int dim_ = 0;
  std::vector<Coupling> couplings_;
  std::vector<Block> blocks_;
  std::unordered_map<std::uint64_t, int> block_of_;  // (a, b) -> index in blocks_
  std::vector<double> values_;
  std::vector<int> positions_;  // per entry of values_: its index in h_'s values, -1 below the diagonal
  std::vector<int> diagonal_;   // per row of H: the index of its diagonal entry in h_'s values
  Eigen::VectorXd g_;
  Eigen::SparseMatrix<double> h_;  // upper triangle
  // The variables are laid out in a fill-reducing order found once (Finalize), so the
  // factorisation keeps that order: no ordering of its own, no permuted copy of H.
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Upper, Eigen::NaturalOrdering<int>> llt_;
  // The dense path: H copied into dense_h_'s lower triangle, factorised there.
  Factorisation factorisation_ = Factorisation::kAuto;
  bool dense_ = false;
  Eigen::Index factor_entries_ = 0;
  Eigen::MatrixXd dense_h_;
  Eigen::LLT<Eigen::MatrixXd, Eigen::Lower> dense_llt_;
  bool finalized_ = false;
  bool factor_is_undamped_ = false;  // llt_ holds H itself (lambda 0), as last accumulated
};

// A nonlinear least-squares problem as the Levenberg-Marquardt driver sees it: a state it can
// linearise, move along a step, and put back.
class LeastSquaresProblem {
 public:
  virtual ~LeastSquaresProblem() = default;
  // Accumulates every factor's normal equations at the current state into eq (already zeroed)
  // and returns the cost 1/2 sum rho(|r|^2).
  virtual double Linearise(BlockNormalEquations& eq) = 0;
  // The cost at the current state.
  virtual double Cost() const = 0;
  // Moves the state by dx (a step over every variable of eq, in its order).
  virtual void Step(const Eigen::VectorXd& dx) = 0;
  // Remembers the state; Restore goes back to it (a refused step).
  virtual void Save() = 0;
  virtual void Restore() = 0;
};

struct LevenbergMarquardtOptions {
  int max_iterations = 100;           // linearisations
  double function_tolerance = 1e-10;  // converged when a step lowers the cost by less than this share of it
  double step_tolerance = 1e-9;       // ... or moves no variable by more than this (m or rad)
  double initial_lambda = 1e-6;       // damping of the first step (share of diag(H))
  // Damping below this (it falls by 3 at each accepted step) is taken as none: the step is
  // Gauss-Newton's, and one smaller than step_tolerance ends the run before it is taken, at a
  // state linearised and factorised already (no further linearisation, and Marginals reuses
  // the factor). Off by default: for problems that start near their minimum (a join warm
  // started from the last one); on a batch from odometry (MRCLAM 7's central optimum)
  // undamped steps are refused often enough that the run no longer converges.
  double undamped_below = 0.0;
};

struct LevenbergMarquardtReport {
  int iterations = 0;  // linearisations
  int steps_accepted = 0;
  bool converged = false;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  std::string stop;  // why it stopped: "cost", "step", "iterations", "not positive definite", "no descent"
};

// Minimises the problem's cost by Levenberg-Marquardt (Nocedal & Wright 10.3; damping
// lambda diag(H), divided by 3 after an accepted step and multiplied by 4 after a refused one).
// eq must be finalized. On return, eq holds the normal equations at the final state.
LevenbergMarquardtReport MinimiseLevenbergMarquardt(LeastSquaresProblem& problem, BlockNormalEquations& eq,
                                                    const LevenbergMarquardtOptions& options = {});

}  // namespace mapmesh
