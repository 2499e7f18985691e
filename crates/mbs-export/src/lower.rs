//! A captured forward pass as an ONNX graph: each recorded burn operation
//! becomes the ONNX node(s) that compute it, the captured values become
//! initializers, and every shape is the fixed one the capture recorded.

use std::collections::{BTreeMap, HashMap};

use burn::backend::capture::TensorId;
use burn::backend::ir::{
    ActivationOperationIr, AvgPool2dOpIr, BaseOperationIr, BinaryOpIr, BoolOperationIr,
    FloatOperationIr, IntOperationIr, ModuleOperationIr, NumericOperationIr, OperationIr,
    PadModeIr, ScalarIr, ScalarOpIr, TensorIr,
};
use burn::tensor::{DType, TensorData};

use crate::capture::Captured;
use crate::proto::{
    AttributeProto, BOOL, FLOAT, GraphProto, INT64, NodeProto, TensorProto, ValueInfoProto,
};

/// The ONNX operator set versions an export may target.
pub const OPSETS: std::ops::RangeInclusive<i64> = 16..=18;

/// Why a captured graph cannot be written as ONNX.
#[derive(Debug, thiserror::Error)]
pub enum LowerError {
    /// An operation with no ONNX form here.
    #[error("the network uses {0}, which the ONNX export does not support")]
    Unsupported(String),
    /// A tensor type with no ONNX form here.
    #[error("a tensor of type {0:?} cannot be exported")]
    DType(DType),
    /// A value the capture should hold is missing.
    #[error("the capture holds no value for tensor {0}")]
    MissingValue(u64),
    /// A captured value could not be read as its type.
    #[error("the captured value of tensor {0} cannot be read: {1}")]
    Value(u64, String),
}

type Result<T> = std::result::Result<T, LowerError>;

/// The names of the graph's runtime inputs and its output.
pub struct Boundary<'a> {
    /// The runtime inputs, in the capture's order.
    pub inputs: &'a [&'a str],
    /// The output.
    pub output: &'a str,
}

/// Writes `captured` as an ONNX graph for operator set `opset`.
pub fn lower(captured: &Captured, boundary: &Boundary, opset: i64) -> Result<GraphProto> {
    let mut graph = Lowering::new(captured, boundary, opset);
    for operation in &captured.graph.graph.operations {
        graph.operation(operation)?;
    }
    Ok(graph.finish(captured, boundary))
}

/// The graph under construction.
struct Lowering<'a> {
    opset: i64,
    output: String,
    values: &'a BTreeMap<TensorId, TensorData>,
    parameter_names: &'a HashMap<TensorId, String>,
    names: HashMap<TensorId, String>,
    nodes: Vec<NodeProto>,
    initializers: Vec<TensorProto>,
    value_info: Vec<ValueInfoProto>,
    constants: usize,
}

impl<'a> Lowering<'a> {
    fn new(captured: &'a Captured, boundary: &Boundary, opset: i64) -> Self {
        let graph = &captured.graph.graph;
        let mut names = HashMap::new();
        for (id, name) in graph.inputs.iter().zip(boundary.inputs) {
            names.insert(*id, name.to_string());
        }
        if let Some(id) = graph.outputs.first() {
            names.insert(*id, boundary.output.to_string());
        }
        Self {
            opset,
            output: boundary.output.to_string(),
            values: &captured.graph.values,
            parameter_names: &captured.parameter_names,
            names,
            nodes: Vec::new(),
            initializers: Vec::new(),
            value_info: Vec::new(),
            constants: 0,
        }
    }

    /// The graph with its inputs and output typed.
    fn finish(self, captured: &Captured, boundary: &Boundary) -> GraphProto {
        let graph = &captured.graph.graph;
        let shape_of = |id: &TensorId| -> Vec<usize> {
            graph
                .operations
                .iter()
                .flat_map(|op| op.nodes())
                .find(|t| t.id == *id)
                .map(|t| t.shape.to_vec())
                .unwrap_or_default()
        };
        let input = graph
            .inputs
            .iter()
            .zip(boundary.inputs)
            .map(|(id, name)| ValueInfoProto::tensor(name, FLOAT, &shape_of(id)))
            .collect();
        let output = graph
            .outputs
            .iter()
            .map(|id| ValueInfoProto::tensor(boundary.output, FLOAT, &shape_of(id)))
            .collect();
        GraphProto {
            node: self.nodes,
            name: "mbs".into(),
            initializer: self.initializers,
            input,
            output,
            value_info: self.value_info,
        }
    }

    /// The name of `tensor`'s value.
    fn name(&mut self, tensor: &TensorIr) -> String {
        self.names
            .entry(tensor.id)
            .or_insert_with(|| format!("t{}", tensor.id.value()))
            .clone()
    }

    /// A node `op_type` from `inputs` to `out`.
    fn node(
        &mut self,
        op_type: &str,
        inputs: Vec<String>,
        out: &TensorIr,
        attribute: Vec<AttributeProto>,
    ) {
        let output = self.name(out);
        if let (Ok(elem_type), false) = (onnx_type(out.dtype), output == self.output) {
            let shape: Vec<usize> = out.shape.to_vec();
            self.value_info
                .push(ValueInfoProto::tensor(&output, elem_type, &shape));
        }
        let name = format!("{op_type}_{}", self.nodes.len());
        self.nodes.push(NodeProto {
            input: inputs,
            output: vec![output],
            name,
            op_type: op_type.into(),
            attribute,
        });
    }

    /// A node `op_type` over tensors.
    fn apply(
        &mut self,
        op_type: &str,
        inputs: &[&TensorIr],
        out: &TensorIr,
        attribute: Vec<AttributeProto>,
    ) {
        let inputs = inputs.iter().map(|t| self.name(t)).collect();
        self.node(op_type, inputs, out, attribute);
    }

    /// An initializer `name` of `data_type` and `dims` from little-endian
    /// bytes.
    fn initializer(&mut self, name: &str, data_type: i32, dims: &[i64], raw_data: Vec<u8>) {
        self.initializers.push(TensorProto {
            dims: dims.to_vec(),
            data_type,
            name: name.to_string(),
            raw_data,
        });
    }

    /// A constant initializer of `data_type` and `dims` from little-endian
    /// bytes; returns its name.
    fn constant(&mut self, data_type: i32, dims: &[i64], raw_data: Vec<u8>) -> String {
        self.constants += 1;
        let name = format!("c{}", self.constants);
        self.initializer(&name, data_type, dims, raw_data);
        name
    }

    /// A 1-D int64 constant.
    fn ints(&mut self, values: &[i64]) -> String {
        let bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(INT64, &[values.len() as i64], bytes)
    }

    /// A 0-D constant holding `scalar` in `tensor`'s element type.
    fn scalar(&mut self, scalar: &ScalarIr, like: &TensorIr) -> Result<String> {
        let value = scalar_value(scalar);
        Ok(match onnx_type(like.dtype)? {
            FLOAT => self.constant(FLOAT, &[], (value as f32).to_le_bytes().to_vec()),
            INT64 => self.constant(INT64, &[], (value as i64).to_le_bytes().to_vec()),
            _ => self.constant(BOOL, &[], vec![u8::from(value != 0.0)]),
        })
    }

    /// A binary node between a tensor and a scalar.
    fn with_scalar(&mut self, op_type: &str, op: &ScalarOpIr) -> Result<()> {
        let lhs = self.name(&op.lhs);
        let rhs = self.scalar(&op.rhs, &op.lhs)?;
        self.node(op_type, vec![lhs, rhs], &op.out, Vec::new());
        Ok(())
    }

    fn binary(&mut self, op_type: &str, op: &BinaryOpIr) {
        self.apply(op_type, &[&op.lhs, &op.rhs], &op.out, Vec::new());
    }

    /// One recorded operation.
    fn operation(&mut self, operation: &OperationIr) -> Result<()> {
        match operation {
            OperationIr::Init(init) => self.init(&init.out),
            OperationIr::Drop(_) => Ok(()),
            OperationIr::BaseFloat(op) | OperationIr::BaseInt(op) | OperationIr::BaseBool(op) => {
                self.base(op)
            }
            OperationIr::NumericFloat(_, op) | OperationIr::NumericInt(_, op) => self.numeric(op),
            OperationIr::Float(_, op) => self.float(op),
            OperationIr::Int(op) => self.int(op),
            OperationIr::Bool(op) => self.boolean(op),
            OperationIr::Module(op) => self.module(op),
            OperationIr::Activation(op) => self.activation(op),
            other => Err(LowerError::Unsupported(short_name(other))),
        }
    }

    /// A tensor made from data: a runtime input (already named) or an
    /// initializer named after its parameter.
    fn init(&mut self, out: &TensorIr) -> Result<()> {
        if self.names.contains_key(&out.id) {
            return Ok(());
        }
        let data = self
            .values
            .get(&out.id)
            .ok_or(LowerError::MissingValue(out.id.value()))?;
        let name = match self.parameter_names.get(&out.id) {
            Some(path) => path.clone(),
            None => format!("value{}", out.id.value()),
        };
        let (data_type, raw_data) =
            tensor_bytes(data).map_err(|e| LowerError::Value(out.id.value(), e))?;
        self.initializer(&name, data_type, &dims(out), raw_data);
        self.names.insert(out.id, name);
        Ok(())
    }

    fn base(&mut self, op: &BaseOperationIr) -> Result<()> {
        match op {
            BaseOperationIr::Reshape(op) => self.reshape_like("Reshape", &op.input, &op.out),
            BaseOperationIr::Expand(op) => self.reshape_like("Expand", &op.input, &op.out),
            BaseOperationIr::SwapDims(op) => {
                let mut perm: Vec<i64> = (0..op.input.shape.num_dims() as i64).collect();
                perm.swap(op.dim1, op.dim2);
                let perm = AttributeProto::ints("perm", &perm);
                self.apply("Transpose", &[&op.input], &op.out, vec![perm]);
            }
            BaseOperationIr::Permute(op) => {
                let perm: Vec<i64> = op.axes.iter().map(|&a| a as i64).collect();
                let perm = AttributeProto::ints("perm", &perm);
                self.apply("Transpose", &[&op.input], &op.out, vec![perm]);
            }
            BaseOperationIr::Slice(op) => self.slice(&op.tensor, &op.ranges, &op.out)?,
            BaseOperationIr::Gather(op) => {
                let axis = AttributeProto::int("axis", op.dim as i64);
                self.apply(
                    "GatherElements",
                    &[&op.tensor, &op.indices],
                    &op.out,
                    vec![axis],
                );
            }
            BaseOperationIr::Cat(op) => {
                let inputs: Vec<&TensorIr> = op.tensors.iter().collect();
                let axis = AttributeProto::int("axis", op.dim as i64);
                self.apply("Concat", &inputs, &op.out, vec![axis]);
            }
            BaseOperationIr::Cast(op) => self.cast(&op.input, &op.out)?,
            BaseOperationIr::Zeros(op) => {
                let data_type = onnx_type(op.out.dtype)?;
                let width = match data_type {
                    BOOL => 1,
                    INT64 => 8,
                    _ => 4,
                };
                let bytes = vec![0; op.out.shape.iter().product::<usize>() * width];
                let name = self.constant(data_type, &dims(&op.out), bytes);
                self.names.insert(op.out.id, name);
            }
            other => return Err(LowerError::Unsupported(short_name(other))),
        }
        Ok(())
    }

    /// `Reshape` or `Expand` of `input` to `out`'s fixed shape.
    fn reshape_like(&mut self, op_type: &str, input: &TensorIr, out: &TensorIr) {
        let input = self.name(input);
        let shape = self.ints(&dims(out));
        self.node(op_type, vec![input, shape], out, Vec::new());
    }

    /// A `Slice` with positive steps.
    fn slice(
        &mut self,
        input: &TensorIr,
        ranges: &[burn::tensor::Slice],
        out: &TensorIr,
    ) -> Result<()> {
        let (mut starts, mut ends, mut axes, mut steps) = (vec![], vec![], vec![], vec![]);
        for (axis, (range, &size)) in ranges.iter().zip(input.shape.iter()).enumerate() {
            let (bounds, step) = range.to_range_and_step(size);
            if step <= 0 {
                return Err(LowerError::Unsupported(
                    "a slice with a negative step".into(),
                ));
            }
            starts.push(bounds.start as i64);
            ends.push(bounds.end as i64);
            axes.push(axis as i64);
            steps.push(step as i64);
        }
        let input = self.name(input);
        let inputs = vec![
            input,
            self.ints(&starts),
            self.ints(&ends),
            self.ints(&axes),
            self.ints(&steps),
        ];
        self.node("Slice", inputs, out, Vec::new());
        Ok(())
    }

    /// A `Cast` to `out`'s element type (an `Identity` when it is the same).
    fn cast(&mut self, input: &TensorIr, out: &TensorIr) -> Result<()> {
        let to = onnx_type(out.dtype)?;
        if onnx_type(input.dtype)? == to {
            self.apply("Identity", &[input], out, Vec::new());
        } else {
            self.apply(
                "Cast",
                &[input],
                out,
                vec![AttributeProto::int("to", i64::from(to))],
            );
        }
        Ok(())
    }

    fn numeric(&mut self, op: &NumericOperationIr) -> Result<()> {
        match op {
            NumericOperationIr::Add(op) => self.binary("Add", op),
            NumericOperationIr::Sub(op) => self.binary("Sub", op),
            NumericOperationIr::Mul(op) => self.binary("Mul", op),
            NumericOperationIr::Div(op) => self.binary("Div", op),
            NumericOperationIr::AddScalar(op) => self.with_scalar("Add", op)?,
            NumericOperationIr::SubScalar(op) => self.with_scalar("Sub", op)?,
            NumericOperationIr::MulScalar(op) => self.with_scalar("Mul", op)?,
            NumericOperationIr::DivScalar(op) => self.with_scalar("Div", op)?,
            NumericOperationIr::GreaterEqualElem(op) => self.with_scalar("GreaterOrEqual", op)?,
            NumericOperationIr::LowerEqualElem(op) => self.with_scalar("LessOrEqual", op)?,
            NumericOperationIr::GreaterElem(op) => self.with_scalar("Greater", op)?,
            NumericOperationIr::LowerElem(op) => self.with_scalar("Less", op)?,
            NumericOperationIr::Neg(op) => self.apply("Neg", &[&op.input], &op.out, Vec::new()),
            NumericOperationIr::Abs(op) => self.apply("Abs", &[&op.input], &op.out, Vec::new()),
            NumericOperationIr::MeanDim(op) => {
                self.reduce("ReduceMean", &op.input, op.axis, &op.out)
            }
            NumericOperationIr::SumDim(op) => self.reduce("ReduceSum", &op.input, op.axis, &op.out),
            NumericOperationIr::Clamp(op) => {
                let input = self.name(&op.tensor);
                let min = self.scalar(&op.min, &op.tensor)?;
                let max = self.scalar(&op.max, &op.tensor)?;
                self.node("Clip", vec![input, min, max], &op.out, Vec::new());
            }
            NumericOperationIr::Pad(op) => self.pad(op)?,
            other => return Err(LowerError::Unsupported(short_name(other))),
        }
        Ok(())
    }

    /// A reduction over one axis, kept: axes as an attribute for
    /// `ReduceMean` below opset 18, as an input otherwise.
    fn reduce(&mut self, op_type: &str, input: &TensorIr, axis: usize, out: &TensorIr) {
        let input = self.name(input);
        let keep = AttributeProto::int("keepdims", 1);
        if op_type == "ReduceMean" && self.opset < 18 {
            let axes = AttributeProto::ints("axes", &[axis as i64]);
            self.node(op_type, vec![input], out, vec![axes, keep]);
        } else {
            let axes = self.ints(&[axis as i64]);
            self.node(op_type, vec![input, axes], out, vec![keep]);
        }
    }

    /// A constant or edge `Pad`.
    fn pad(&mut self, op: &burn::backend::ir::PadOpIr) -> Result<()> {
        let begins = op.padding.iter().map(|(before, _)| *before as i64);
        let ends = op.padding.iter().map(|(_, after)| *after as i64);
        let pads: Vec<i64> = begins.chain(ends).collect();
        let input = self.name(&op.input);
        let pads = self.ints(&pads);
        let (mode, inputs) = match &op.mode {
            PadModeIr::Constant(value) => (
                "constant",
                vec![input, pads, self.scalar(value, &op.input)?],
            ),
            PadModeIr::Edge => ("edge", vec![input, pads]),
            PadModeIr::Reflect => ("reflect", vec![input, pads]),
        };
        let mode = AttributeProto::string("mode", mode);
        self.node("Pad", inputs, &op.out, vec![mode]);
        Ok(())
    }

    fn float(&mut self, op: &FloatOperationIr) -> Result<()> {
        match op {
            FloatOperationIr::Sqrt(op) => self.apply("Sqrt", &[&op.input], &op.out, Vec::new()),
            FloatOperationIr::Tanh(op) => self.apply("Tanh", &[&op.input], &op.out, Vec::new()),
            FloatOperationIr::Floor(op) => self.apply("Floor", &[&op.input], &op.out, Vec::new()),
            FloatOperationIr::Exp(op) => self.apply("Exp", &[&op.input], &op.out, Vec::new()),
            FloatOperationIr::IntoInt(op) => self.cast(&op.input, &op.out)?,
            FloatOperationIr::Matmul(op) => {
                self.apply("MatMul", &[&op.lhs, &op.rhs], &op.out, Vec::new())
            }
            other => return Err(LowerError::Unsupported(short_name(other))),
        }
        Ok(())
    }

    fn int(&mut self, op: &IntOperationIr) -> Result<()> {
        match op {
            IntOperationIr::IntoFloat(op) => self.cast(&op.input, &op.out),
            other => Err(LowerError::Unsupported(short_name(other))),
        }
    }

    fn boolean(&mut self, op: &BoolOperationIr) -> Result<()> {
        match op {
            BoolOperationIr::IntoFloat(op) => self.cast(&op.input, &op.out),
            BoolOperationIr::IntoInt(op) => self.cast(&op.input, &op.out),
            BoolOperationIr::And(op) => {
                self.binary("And", op);
                Ok(())
            }
            other => Err(LowerError::Unsupported(short_name(other))),
        }
    }

    fn activation(&mut self, op: &ActivationOperationIr) -> Result<()> {
        match op {
            ActivationOperationIr::Relu(op) => {
                self.apply("Relu", &[&op.input], &op.out, Vec::new())
            }
            ActivationOperationIr::Sigmoid(op) => {
                self.apply("Sigmoid", &[&op.input], &op.out, Vec::new())
            }
            ActivationOperationIr::LeakyRelu(op) => {
                let alpha = scalar_value(&op.rhs) as f32;
                let alpha = AttributeProto::float("alpha", alpha);
                self.apply("LeakyRelu", &[&op.lhs], &op.out, vec![alpha]);
            }
            ActivationOperationIr::Softmax(op) => {
                let axis = AttributeProto::int("axis", op.axis as i64);
                self.apply("Softmax", &[&op.input], &op.out, vec![axis]);
            }
            other => return Err(LowerError::Unsupported(short_name(other))),
        }
        Ok(())
    }

    fn module(&mut self, op: &ModuleOperationIr) -> Result<()> {
        let (op_type, inputs, out, attributes) = match op {
            ModuleOperationIr::Conv2d(op) => {
                let (o, p) = (&op.options, op.options.padding);
                let pads = [p[0].0, p[1].0, p[0].1, p[1].1];
                let attributes =
                    conv_attributes(&o.stride, &pads, &o.dilation, o.groups, &op.weight);
                (
                    "Conv",
                    conv_inputs(&op.x, &op.weight, &op.bias),
                    &op.out,
                    attributes,
                )
            }
            ModuleOperationIr::Conv3d(op) => {
                let o = &op.options;
                let pads = [o.padding, o.padding].concat();
                let attributes =
                    conv_attributes(&o.stride, &pads, &o.dilation, o.groups, &op.weight);
                let inputs = conv_inputs(&op.x, &op.weight, &op.bias);
                ("Conv", inputs, &op.out, attributes)
            }
            ModuleOperationIr::ConvTranspose2d(op) => {
                let o = &op.options;
                let sides = [&o.stride[..], &o.padding, &o.padding_out, &o.dilation];
                let attributes = transposed_attributes(sides, o.groups, &op.weight);
                let inputs = conv_inputs(&op.x, &op.weight, &op.bias);
                ("ConvTranspose", inputs, &op.out, attributes)
            }
            ModuleOperationIr::ConvTranspose3d(op) => {
                let o = &op.options;
                let sides = [&o.stride[..], &o.padding, &o.padding_out, &o.dilation];
                let attributes = transposed_attributes(sides, o.groups, &op.weight);
                let inputs = conv_inputs(&op.x, &op.weight, &op.bias);
                ("ConvTranspose", inputs, &op.out, attributes)
            }
            ModuleOperationIr::AvgPool2d(op) => {
                self.average_pool(op);
                return Ok(());
            }
            other => return Err(LowerError::Unsupported(short_name(other))),
        };
        self.apply(op_type, &inputs, out, attributes);
        Ok(())
    }

    /// An `AveragePool` node.
    fn average_pool(&mut self, op: &AvgPool2dOpIr) {
        let pads = [op.padding, op.padding].concat();
        let attributes = vec![
            usize_list("kernel_shape", &op.kernel_size),
            usize_list("strides", &op.stride),
            usize_list("pads", &pads),
            AttributeProto::int("count_include_pad", i64::from(op.count_include_pad)),
            AttributeProto::int("ceil_mode", i64::from(op.ceil_mode)),
        ];
        self.apply("AveragePool", &[&op.x], &op.out, attributes);
    }
}

/// A convolution's inputs: the input, the weight and the bias when it has one.
fn conv_inputs<'t>(
    x: &'t TensorIr,
    weight: &'t TensorIr,
    bias: &'t Option<TensorIr>,
) -> Vec<&'t TensorIr> {
    let mut inputs = vec![x, weight];
    inputs.extend(bias.as_ref());
    inputs
}

/// A convolution's attributes; `kernel_shape` from the weight's shape.
fn conv_attributes(
    strides: &[usize],
    pads: &[usize],
    dilations: &[usize],
    groups: usize,
    weight: &TensorIr,
) -> Vec<AttributeProto> {
    vec![
        usize_list("kernel_shape", &weight.shape[2..]),
        usize_list("strides", strides),
        usize_list("pads", pads),
        usize_list("dilations", dilations),
        AttributeProto::int("group", groups as i64),
    ]
}

/// A transposed convolution's attributes from its `[stride, padding,
/// output padding, dilation]` per spatial axis.
fn transposed_attributes(
    sides: [&[usize]; 4],
    groups: usize,
    weight: &TensorIr,
) -> Vec<AttributeProto> {
    let [stride, padding, padding_out, dilation] = sides;
    let pads = [padding, padding].concat();
    let mut attributes = conv_attributes(stride, &pads, dilation, groups, weight);
    attributes.push(usize_list("output_padding", padding_out));
    attributes
}

/// `tensor`'s shape as ONNX dimensions.
fn dims(tensor: &TensorIr) -> Vec<i64> {
    tensor.shape.iter().map(|&side| side as i64).collect()
}

/// An integer-list attribute from sizes.
fn usize_list(name: &str, values: &[usize]) -> AttributeProto {
    let values: Vec<i64> = values.iter().map(|&v| v as i64).collect();
    AttributeProto::ints(name, &values)
}

/// A scalar's value as a float.
fn scalar_value(scalar: &ScalarIr) -> f64 {
    match scalar {
        ScalarIr::Float(v) => *v,
        ScalarIr::Int(v) => *v as f64,
        ScalarIr::UInt(v) => *v as f64,
        ScalarIr::Bool(v) => f64::from(u8::from(*v)),
    }
}

/// An operation's variant name, for an error.
fn short_name(operation: &impl std::fmt::Debug) -> String {
    let text = format!("{operation:?}");
    text.chars()
        .take_while(|c| *c != '(' && *c != '{' && *c != ' ')
        .collect()
}

/// The ONNX element type of `dtype`.
fn onnx_type(dtype: DType) -> Result<i32> {
    match dtype {
        DType::F32 | DType::Flex32 => Ok(FLOAT),
        DType::I64
        | DType::I32
        | DType::I16
        | DType::I8
        | DType::U64
        | DType::U32
        | DType::U16
        | DType::U8 => Ok(INT64),
        DType::Bool(_) => Ok(BOOL),
        other => Err(LowerError::DType(other)),
    }
}

/// `data` as an ONNX element type and little-endian bytes (integers as
/// int64); an error names a value that cannot be read as its type.
fn tensor_bytes(data: &TensorData) -> std::result::Result<(i32, Vec<u8>), String> {
    let data_type = onnx_type(data.dtype()).map_err(|e| e.to_string())?;
    let bytes = match data_type {
        FLOAT => le_bytes(
            data.clone().convert::<f32>().try_to_vec::<f32>(),
            f32::to_le_bytes,
        ),
        INT64 => le_bytes(
            data.clone().convert::<i64>().try_to_vec::<i64>(),
            i64::to_le_bytes,
        ),
        _ => le_bytes(data.clone().try_to_vec::<bool>(), |v| [u8::from(v)]),
    };
    Ok((data_type, bytes?))
}

/// The little-endian bytes of `values`.
fn le_bytes<T: Copy, const N: usize, E: std::fmt::Debug>(
    values: std::result::Result<Vec<T>, E>,
    to_bytes: fn(T) -> [u8; N],
) -> std::result::Result<Vec<u8>, String> {
    let values = values.map_err(|e| format!("{e:?}"))?;
    Ok(values.into_iter().flat_map(to_bytes).collect())
}
